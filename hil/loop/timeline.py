"""The phases of a run, by tick: hold, re-homing, the experiment, stop cycles.

    tick 0 .. S-1               HOLD: the present position (S = [loop] stop_cycles)
    .. S+H-1                    HOMING: only if the link starts away from the experiment's
                                start: the slow ramp (hil/loop/homing.py), H ticks
    .. S+H+E-1 (experiment end) EXPERIMENT: controller + supervisor along the reference
    last S ticks                STOP: hold the last goal, then the configured exit state
The experiment's own time is loop time minus the re-homing: t_exp = (k - H) x period. (Without
re-homing the experiment's time starts at tick 0, with the hold: the reference there is its
start value.)
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass


class Phase(enum.StrEnum):
    HOLD = "hold"
    HOMING = "homing"
    EXPERIMENT = "experiment"
    STOP = "stop"


@dataclass(frozen=True)
class Timeline:
    """Tick boundaries of the phases; see the module docstring."""

    period_s: float
    hold_ticks: int
    experiment_ticks: int
    homing_ticks: int = 0

    @classmethod
    def plan(cls, period_s: float, hold_ticks: int, duration_s: float) -> Timeline:
        return cls(period_s, hold_ticks, int(round(duration_s / period_s)))

    def with_homing(self, homing_ticks: int) -> Timeline:
        return Timeline(self.period_s, self.hold_ticks, self.experiment_ticks, homing_ticks)

    @property
    def experiment_end(self) -> int:
        """The first tick after the experiment (stop cycles from here)."""
        return self.experiment_ticks + self.homing_ticks

    @property
    def end(self) -> int:
        """The first tick after the run."""
        return self.experiment_end + self.hold_ticks

    @property
    def experiment_start_s(self) -> float:
        """Loop time at which the experiment's timeline starts."""
        return self.homing_ticks * self.period_s

    def phase(self, tick: int) -> Phase:
        if tick >= self.experiment_end:
            return Phase.STOP
        if tick < self.hold_ticks:
            return Phase.HOLD
        if tick < self.hold_ticks + self.homing_ticks:
            return Phase.HOMING
        return Phase.EXPERIMENT

    def experiment_time_s(self, tick: int) -> float:
        return tick * self.period_s - self.homing_ticks * self.period_s

    def ticks_for(self, seconds: float) -> int:
        return math.ceil(seconds / self.period_s - 1e-9)
