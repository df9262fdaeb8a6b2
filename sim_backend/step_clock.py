"""An emulated plant's clock, counted in whole physics steps.

A float summed step by step drifts, and a fault or push due at exactly t would then start a
step late (or early): the plant counts steps and multiplies. The scenario clock (pushes,
faults) starts at the first SYNC (`start_scenario`). `steps_covering` turns a duration into
whole steps and carries the remainder to the next call.
"""

from __future__ import annotations

import math


class StepClock:
    def __init__(self, dt_s: float) -> None:
        self.dt_s = dt_s
        self.steps = 0
        self._origin_step: int | None = None
        self._carry_s = 0.0

    @property
    def time_s(self) -> float:
        return self.steps * self.dt_s

    def start_scenario(self) -> None:
        if self._origin_step is None:
            self._origin_step = self.steps

    @property
    def scenario_time_s(self) -> float | None:
        """Time since the scenario started, None before."""
        if self._origin_step is None:
            return None
        return (self.steps - self._origin_step) * self.dt_s

    def steps_covering(self, duration_s: float) -> int:
        """Whole steps for duration_s plus what the last call left over."""
        total = self._carry_s + duration_s
        steps = int(math.floor(total / self.dt_s + 1e-9))
        self._carry_s = total - steps * self.dt_s
        return steps
