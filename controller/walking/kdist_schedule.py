"""Kdist per leg as a pure function of the walking phase (Kim et al., ICRA 2018, Sec. IV-C).

The paper: "Kdist was set to 0.2 ... always except for the landing period. During the landing
phase, the gain of the landing leg was changed to 1.0". The lab's code (psh117/dyros_jet,
`dyros_jet_controller/src/walking_controller.cpp`, BSD-2-Clause (c) 2017 Suhan Park) shapes the
landing period per leg as:

    stance (and any leg outside its landing period): stance_gain (0.2)
    landing leg, last ramp_up_s (0.1 s) of its single support: cubic stance -> landing gain,
        reaching landing_gain (1.0) at the nominal touchdown (end of single support)
    landing leg, the double support after its touchdown: held at landing_gain, then a cubic
        back to stance_gain over release_s, ending at the end of the step.

The cubic is c(s) = 3 s^2 - 2 s^3 (zero slope at both ends). "The end of the step": with
hold_after_touchdown_s = None (default) the release ends with the double support (the next
lift-off); with a number, the gain holds that long after touchdown and then releases. The lab's
timing on its master branch (step 1.2 s: rest 0.05, DSP 0.1, SSP 0.9, DSP 0.1, rest 0.05) is
hold_after_touchdown_s = 0.1, release_s = 0.05 in this module's terms (its DSP 0.1 + rest 0.05
+ rest 0.05 + DSP 0.1 are one 0.3 s double support here). `KdistSchedule.lab_split` maps any
double support onto that split (the ZMP reference's `ZmpTransition.LAB_SPLIT`): hold through
DSP2 (t_double), release over rest_last (half of what the two moves leave).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from controller.walking.footsteps import FootstepPlanError, Side, StepTiming
from controller.walking.timeline import PhaseSample, SegmentKind


@dataclass(frozen=True)
class KdistSchedule:
    stance_gain: float = 0.2
    landing_gain: float = 1.0
    ramp_up_s: float = 0.1
    release_s: float = 0.05
    hold_after_touchdown_s: float | None = None

    def __post_init__(self) -> None:
        for name in ("stance_gain", "landing_gain"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {value}")
        for name in ("ramp_up_s", "release_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be finite and > 0, got {value}")
        hold = self.hold_after_touchdown_s
        if hold is not None and not (math.isfinite(hold) and hold >= 0):
            raise ValueError(f"hold_after_touchdown_s must be None or >= 0, got {hold}")

    @classmethod
    def lab_split(
        cls, stance_gain: float, double_support_s: float, move_s: float, **gains: float
    ) -> KdistSchedule:
        """The lab's landing gain on its step split (module docstring): held for DSP2
        (`move_s`, its t_double) after the touchdown, released over rest_last, the half of the
        double support the two moves leave; `gains`: landing_gain, ramp_up_s."""
        rest_s = 0.5 * (double_support_s - 2.0 * move_s)
        if not rest_s > 0.0:
            raise FootstepPlanError(
                f"the lab's split needs a double support longer than 2 x {move_s} s, got "
                f"{double_support_s} s"
            )
        return cls(
            stance_gain=stance_gain, release_s=rest_s, hold_after_touchdown_s=move_s, **gains
        )

    def check_timing(self, timing: StepTiming) -> None:
        """Raise FootstepPlanError if the ramps do not fit in the plan's phases."""
        if self.ramp_up_s > timing.single_support_s + 1e-12:
            raise FootstepPlanError(
                f"Kdist ramp_up_s = {self.ramp_up_s} s is longer than the single support "
                f"({timing.single_support_s} s)"
            )
        landing = self.release_s + (self.hold_after_touchdown_s or 0.0)
        if landing > timing.double_support_s + 1e-12:
            raise FootstepPlanError(
                f"Kdist hold + release = {landing} s is longer than the double support "
                f"({timing.double_support_s} s)"
            )


def _cubic(start: float, end: float, s: float) -> float:
    if s <= 0.0:
        return start
    if s >= 1.0:
        return end
    return start + (end - start) * s * s * (3.0 - 2.0 * s)


def kdist_gain(side: Side, phase: PhaseSample, schedule: KdistSchedule) -> float:
    """Kdist of leg `side` at this phase sample (module docstring)."""
    if phase.landing_side is not side:
        return schedule.stance_gain
    if phase.kind is SegmentKind.SINGLE_SUPPORT:
        # Ramp over the last ramp_up_s before the nominal touchdown.
        s = 1.0 - phase.time_to_phase_end_s / schedule.ramp_up_s
        return _cubic(schedule.stance_gain, schedule.landing_gain, s)
    # The double support after this leg's touchdown.
    if schedule.hold_after_touchdown_s is None:
        release_start = phase.phase_duration_s - schedule.release_s
    else:
        release_start = schedule.hold_after_touchdown_s
    s = (phase.time_in_phase_s - release_start) / schedule.release_s
    return _cubic(schedule.landing_gain, schedule.stance_gain, s)


def kdist_per_joint(phase: PhaseSample, schedule: KdistSchedule) -> np.ndarray:
    """Kdist for the 12 leg joints (left hip yaw..ankle roll, then right): each leg's gain on
    all six of its joints, as the lab's code schedules it."""
    left = kdist_gain(Side.LEFT, phase, schedule)
    right = kdist_gain(Side.RIGHT, phase, schedule)
    return np.repeat([left, right], 6)
