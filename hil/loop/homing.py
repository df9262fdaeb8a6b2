"""Back to a known state before an experiment: the slow re-homing.

After an actuator's protection tripped, the link rests wherever it fell (on the block, after the
contact experiment); after `hil reboot` or `hil run --reboot-first` the actuator holds that
position with torque off. The experiment's reference starts elsewhere. The loop must not let
the controller (or the goal rate limit, 2 rad/s) rush there: it re-homes slowly.

The plan, decided once from the first sample of a run:
    if every joint's measured link angle is within `tolerance_rad` of the experiment's first
    reference, there is nothing to do (the normal case: no homing, the timeline is unchanged);
    else the loop's reference follows a cosine ramp from the measured link angle to the first
    reference, its duration chosen so that no joint's reference moves faster than `rate_rad_s`
    (peak speed of a cosine ramp: pi/2 x distance / duration), then holds there `settle_s`.
The experiment's own timeline starts after that: experiment time = loop time - duration_s.
The ramp is followed by the actuator's own position servo (goal motor angle = the ramp): the
most predictable behaviour after a fault, with a command that itself never moves faster than the
rate. The link then lags by the gravity sag through gear and servo (about 0.01 rad on the
testbed); the run's controller starts bumplessly from there when the experiment begins. The
supervisor watches the homing like any other part of the run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

REHOME_RATE_RAD_S = 0.1  # the reference's peak speed while re-homing
REHOME_TOLERANCE_RAD = 0.01  # closer than this to the start: no re-homing
REHOME_SETTLE_S = 0.5  # hold at the start before the experiment's timeline begins


@dataclass(frozen=True)
class HomingPlan:
    """A cosine ramp of the link reference per joint, then a hold (see the module docstring)."""

    start_rad: np.ndarray  # measured link angles at the first tick
    target_rad: np.ndarray  # the experiment's first reference
    ramp_s: float
    settle_s: float
    rate_rad_s: float

    @property
    def duration_s(self) -> float:
        return self.ramp_s + self.settle_s

    def ticks(self, period_s: float) -> int:
        """Loop ticks the plan needs at this period (whole ticks, rounded up)."""
        return math.ceil(self.duration_s / period_s - 1e-9)

    def reference(self, time_s: float) -> np.ndarray:
        """The reference [rad] `time_s` after the ramp started (start before, target after)."""
        if time_s <= 0.0:
            return self.start_rad.copy()
        if time_s >= self.ramp_s:
            return self.target_rad.copy()
        phase = 0.5 * (1.0 - math.cos(math.pi * time_s / self.ramp_s))
        return self.start_rad + (self.target_rad - self.start_rad) * phase

    def describe(self) -> str:
        distance = float(np.max(np.abs(self.target_rad - self.start_rad)))
        return (
            f"re-homing: link from {_angles(self.start_rad)} to {_angles(self.target_rad)} rad "
            f"({distance:.3f} rad) over {self.ramp_s:.2f} s at <= {self.rate_rad_s:g} rad/s, "
            f"then {self.settle_s:g} s settling; the experiment starts after "
            f"{self.duration_s:.2f} s"
        )

    def to_dict(self) -> dict[str, object]:
        return {
            "start_rad": self.start_rad.tolist(),
            "target_rad": self.target_rad.tolist(),
            "ramp_s": self.ramp_s,
            "settle_s": self.settle_s,
            "rate_rad_s": self.rate_rad_s,
            "duration_s": self.duration_s,
        }


def plan_homing(
    link_angle_rad: np.ndarray,
    target_rad: np.ndarray | float,
    *,
    rate_rad_s: float = REHOME_RATE_RAD_S,
    tolerance_rad: float = REHOME_TOLERANCE_RAD,
    settle_s: float = REHOME_SETTLE_S,
) -> HomingPlan | None:
    """The re-homing plan from the measured link angles, or None when already at the start."""
    if not rate_rad_s > 0:
        raise ValueError(f"the re-homing rate must be > 0 rad/s, got {rate_rad_s}")
    if not tolerance_rad >= 0 or not settle_s >= 0:
        raise ValueError("the re-homing tolerance and settling time must be >= 0")
    start = np.array(link_angle_rad, dtype=float)
    target = np.broadcast_to(np.asarray(target_rad, dtype=float), start.shape).copy()
    if not (np.isfinite(start).all() and np.isfinite(target).all()):
        raise ValueError(
            f"cannot plan a re-homing from {start.tolist()} to {target.tolist()} rad: every "
            "link angle must be known"
        )
    distance = float(np.max(np.abs(target - start)))
    if distance <= tolerance_rad:
        return None
    ramp_s = 0.5 * math.pi * distance / rate_rad_s
    return HomingPlan(start, target, ramp_s, settle_s, rate_rad_s)


def _angles(values: np.ndarray) -> str:
    return ", ".join(f"{v:+.3f}" for v in values)
