"""The ZMP reference implied by a footstep plan, per tick.

Piecewise per support (Kajita et al., ICRA 2003, Sec. III: the ZMP reference follows the
footsteps): constant at the stance foot's ZMP point during single support, constant between the
feet during the rests, and a transition during each double support from where it was to where
the next single support (or the final rest) needs it. The reference is continuous: a jump would
be an instantaneous ZMP error of the jump's size, since the cart-table's ZMP
p - (zc/g) p'' is continuous under a jerk input.

A foot's ZMP point is its ankle projection plus an offset in the foot frame: forward_offset_m
along the foot and inward_offset_m towards the other foot (the lab's code shifted its
reference 0.02-0.04 m inward; the default here is 0).

The reference asks no more preview than the plan holds when the plan starts with a rest at
least as long as the preview horizon (the preview then sees only the constant rest value from
tick 0, so the rest state is the controller's exact equilibrium) and ends with a rest (the
reference beyond the plan is the final rest value, which is what the robot does after the plan).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

import numpy as np

from controller.walking.footsteps import Footstep, FootstepPlanError, Side
from controller.walking.timeline import SegmentKind, WalkTimeline


class ZmpTransition(Enum):
    """Shape of the double-support transition, s in [0, 1): LINEAR s, SMOOTH 3 s^2 - 2 s^3
    (zero slope at both ends)."""

    LINEAR = "linear"
    SMOOTH = "smooth"

    def blend(self, s: np.ndarray) -> np.ndarray:
        if self is ZmpTransition.LINEAR:
            return s
        return s * s * (3.0 - 2.0 * s)


@dataclass(frozen=True)
class ZmpReferenceParams:
    transition: ZmpTransition = ZmpTransition.LINEAR
    forward_offset_m: float = 0.0
    inward_offset_m: float = 0.0

    def __post_init__(self) -> None:
        if not isinstance(self.transition, ZmpTransition):
            raise FootstepPlanError(f"transition must be a ZmpTransition, got {self.transition!r}")
        for name in ("forward_offset_m", "inward_offset_m"):
            if not math.isfinite(getattr(self, name)):
                raise FootstepPlanError(f"{name} must be finite, got {getattr(self, name)}")


def foot_zmp_point(step: Footstep, params: ZmpReferenceParams) -> np.ndarray:
    """The ZMP reference point of one foot (x, y) [m]."""
    along = params.forward_offset_m
    lateral = -step.side.lateral_sign * params.inward_offset_m  # towards the other foot
    c, s = math.cos(step.yaw_rad), math.sin(step.yaw_rad)
    return np.array([step.x_m + c * along - s * lateral, step.y_m + s * along + c * lateral])


def zmp_reference(timeline: WalkTimeline, params: ZmpReferenceParams) -> np.ndarray:
    """The ZMP reference (n_ticks, 2) [m] of the timeline's plan."""
    plan = timeline.plan
    feet = {Side.LEFT: plan.initial_left, Side.RIGHT: plan.initial_right}

    def midpoint() -> np.ndarray:
        left, right = (
            foot_zmp_point(feet[Side.LEFT], params),
            foot_zmp_point(feet[Side.RIGHT], params),
        )
        return 0.5 * (left + right)

    reference = np.empty((timeline.n_ticks, 2))
    current = midpoint()
    targets: list[np.ndarray] = []
    # The ZMP target each segment ends at, in segment order (feet updated at touchdowns).
    for seg in timeline.segments:
        if seg.kind is SegmentKind.SINGLE_SUPPORT:
            step = plan.footsteps[seg.footstep_index]
            targets.append(foot_zmp_point(feet[step.side.other], params))
            feet[step.side] = step  # lands at the end of this segment
        elif seg.kind is SegmentKind.DOUBLE_SUPPORT:
            targets.append(np.empty(2))  # filled below: the next segment's value
        else:
            targets.append(midpoint())
    for index, seg in enumerate(timeline.segments):
        if seg.kind is SegmentKind.DOUBLE_SUPPORT:
            targets[index] = targets[index + 1]
    for seg, target in zip(timeline.segments, targets, strict=True):
        rows = slice(seg.start_tick, seg.end_tick)
        if seg.kind is SegmentKind.DOUBLE_SUPPORT:
            s = np.arange(seg.n_ticks) / seg.n_ticks
            weight = params.transition.blend(s)[:, None]
            reference[rows] = (1.0 - weight) * current + weight * target
        else:
            reference[rows] = target
        current = target
    return reference
