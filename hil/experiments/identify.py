"""Identification excitation (`hil run identify`): a chirp on the goal with the link free, for
`hil identify` to fit the joint's constants from the log.

The link is free (no obstacle, no push). The experiment holds, then sweeps the goal with the
rate-limited logarithmic chirp of `hil.identify.excitation` - up from 0.2 Hz to 10 Hz over 30 s
(the part the fit uses), back down over 12 s (held out to measure how well the model predicts)
- then holds again; 46 s in all. It is open loop: the goal is the goal in force when the
experiment starts plus the chirp's offset, with no controller in the loop, so the log shows the
actuator's own servo and the gear, which is what the fit models. The supervisor still checks
and limits every goal: the chirp stays within ChirpExcitation's amplitude around the holding
angle (checked against the joint's limits before the run) and moves the goal at most at
1.6 rad/s, below the supervisor's goal-rate limit (2 rad/s by default; the loop refuses an
excitation faster than the configured limit), so the supervisor never rewrites it. The same
experiment runs on the emulator and on hardware.

Metrics (from the run's log, over all joints):
    peak_current_a          largest |motor current| during the experiment
    peak_goal_rate_rad_s    largest goal step per period, as a rate
    excitation_coverage     share of the experiment's ticks whose goal was the planned one
                            (goal in force at the start + the chirp's offset, within 1 urad):
                            1.0 when nothing (a limit, a safety hold, a torque off) rewrote it
    validation_start_s      loop time at which the held-out down-sweep begins (what
                            `hil identify` passes to the fit)
The excitation's parameters go to meta.json (`experiment_parameters`); the current limit the
run read from the actuator's Torque Limit to summary.json (`current_limit_a`).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from hil.experiments.base import Experiment, World
from hil.identify import ChirpExcitation, chirp_goal_offsets
from hil.output.report import Column, number
from hil.output.rundir import RunData

PLANNED_GOAL_TOLERANCE_RAD = 1e-6  # the log keeps 9 decimals
# An open-loop excitation's report columns (`excitation_metrics`)
EXCITATION_COLUMNS = (
    Column("peak_current_a", "peak current [A]", number(".2f")),
    Column("peak_goal_rate_rad_s", "peak goal rate [rad/s]", number(".2f")),
    Column("excitation_coverage", "coverage", number(".3f")),
)


def excitation_metrics(run: RunData, planned_at: Callable[[float], np.ndarray]) -> dict[str, float]:
    """An open-loop excitation's metrics (the module docstring's first three) from a run's log;
    `planned_at(period_s)`: the planned goal offsets per tick, (ticks,) for every joint or
    (ticks, joints)."""
    phase = run.columns.get("phase")
    if phase is None:
        raise ValueError("the log has no phase column")
    rows = np.flatnonzero(phase == "experiment")
    if rows.size < 2:
        return {"excitation_coverage": 0.0}
    period = float(np.median(np.diff(run.time_s)))
    first_tick = int(round((run.time_s[rows[0]] - run.experiment_start_s) / period))
    planned = planned_at(period)
    index = np.clip(first_tick + np.arange(rows.size), 0, len(planned) - 1)
    peak_current, peak_rate, coverage = 0.0, 0.0, 1.0
    for column, joint in enumerate(run.joint_names):
        current = np.abs(run.signal("motor_current_a", joint)[rows])
        goal = run.signal("goal_rad", joint)[rows]
        peak_current = max(peak_current, float(np.nanmax(current)))
        steps = np.abs(np.diff(goal))
        peak_rate = max(peak_rate, float(np.nanmax(steps, initial=0.0)) / period)
        own = planned if planned.ndim == 1 else planned[:, column]
        expected = goal[0] - own[index[0]] + own[index]
        followed = np.abs(goal - expected) <= PLANNED_GOAL_TOLERANCE_RAD
        coverage = min(coverage, float(np.count_nonzero(followed)) / rows.size)
    return {
        "peak_current_a": peak_current,
        "peak_goal_rate_rad_s": peak_rate,
        "excitation_coverage": coverage,
    }


@dataclass(frozen=True)
class IdentifyExperiment(Experiment):
    """The chirp of `excitation` on the goal around its holding angle; see the module doc."""

    name: str
    title: str
    excitation: ChirpExcitation
    world: World = World()

    @property
    def duration_s(self) -> float:  # type: ignore[override]
        return self.excitation.duration_s

    @property
    def open_loop(self) -> bool:
        return True

    @functools.cached_property
    def _offsets(self) -> np.ndarray:
        return chirp_goal_offsets(self.excitation).goal_offset_rad

    def _offsets_at(self, period_s: float) -> np.ndarray:
        if abs(period_s - self.excitation.period_s) < 1e-12:
            return self._offsets
        excitation = dataclasses.replace(self.excitation, period_s=period_s)
        return chirp_goal_offsets(excitation).goal_offset_rad

    # --- what the loop follows ------------------------------------------------------------
    def reference(self, time_s: float) -> float:
        """The link's nominal path: the holding angle plus the goal's offset."""
        offsets = self._offsets
        index = int(round(time_s / self.excitation.period_s))
        offset = offsets[index] if 0 <= index < len(offsets) else 0.0
        return self.excitation.holding_angle_rad + float(offset)

    def reference_range(self, n_joints: int) -> tuple[np.ndarray, np.ndarray]:
        swing = float(np.abs(self._offsets).max(initial=0.0))
        hold = self.excitation.holding_angle_rad
        return np.full(n_joints, hold - swing), np.full(n_joints, hold + swing)

    def goal_offsets(self, period_s: float, ticks: int, n_joints: int) -> np.ndarray:
        offsets = self._offsets_at(period_s)[:ticks]
        table = np.zeros((ticks, n_joints))
        table[: len(offsets)] = offsets[:, None]
        return table

    def parameters(self) -> dict[str, Any]:
        return {
            "excitation": "chirp",
            **dataclasses.asdict(self.excitation),
            "duration_s": self.excitation.duration_s,
            "validation_start_after_experiment_start_s": self.excitation.validation_start_s,
        }

    # --- after a run -----------------------------------------------------------------------
    def metrics(self, run: RunData) -> dict[str, Any]:
        figures = excitation_metrics(run, self._offsets_at)
        if "peak_current_a" not in figures:
            return figures
        return {
            **figures,
            "validation_start_s": run.experiment_start_s + self.excitation.validation_start_s,
        }

    @property
    def report_columns(self) -> tuple[Column, ...]:
        return EXCITATION_COLUMNS


IDENTIFY = IdentifyExperiment(
    name="identify",
    title="Identification: a chirp on the goal with the link free (for `hil identify`)",
    excitation=ChirpExcitation(),
)
