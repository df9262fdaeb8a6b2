"""The ZMP reference implied by a footstep plan, per tick.

Piecewise per support (Kajita et al., ICRA 2003, Sec. III: the ZMP reference follows the
footsteps): constant at the stance foot's ZMP point during single support, constant between the
feet during the rests, and a transition during each double support from where it was to where
the next single support (or the final rest) needs it. The reference is continuous: a jump would
be an instantaneous ZMP error of the jump's size, since the cart-table's ZMP
p - (zc/g) p'' is continuous under a jerk input.

A foot's ZMP point is its ankle projection plus an offset in the foot frame: forward_offset_m
along the foot and inward_offset_m towards the other foot (the lab's code shifts its reference
inward by 0.02 m in 2018 and 0.04 m on master: psh117/dyros_jet, walking_controller.cpp,
`addZmpOffset`, lfoot_zmp_offset_ / rfoot_zmp_offset_; the default here is 0).

The double-support transition (`ZmpTransition`):
    LINEAR, SMOOTH   one move over the whole double support, from the stance foot it leaves to
                     the one it goes to (ours);
    LAB_SPLIT        the lab's step timing (walking_controller.cpp, `onestepZmp`): a step is
                     rest_init, DSP1 (t_double1), SSP, DSP2 (t_double2), rest_last, so the
                     double support between two single supports is DSP2 + rest_last + the next
                     step's rest_init + DSP1. The ZMP moves linearly in DSP2 from the foot it
                     leaves to the middle of the feet, holds there through the rests, and moves
                     linearly in DSP1 to the next stance foot. `lab_move_s` is t_double (0.1 s
                     in 2018 and on master), each ramp reaching its end value on its last tick as
                     the lab's K / t_double (i + 1) does. A double support with nothing to leave
                     (the walk's first) holds the middle, one with nowhere to go (the last)
                     stays there.

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
    """Shape of the double-support transition (module docstring); for the one-move shapes,
    s in [0, 1): LINEAR s, SMOOTH 3 s^2 - 2 s^3 (zero slope at both ends)."""

    LINEAR = "linear"
    SMOOTH = "smooth"
    LAB_SPLIT = "lab-split"

    def blend(self, s: np.ndarray) -> np.ndarray:
        if self is ZmpTransition.LINEAR:
            return s
        if self is ZmpTransition.SMOOTH:
            return s * s * (3.0 - 2.0 * s)
        raise ValueError("the lab's split is two moves, not one blend")


@dataclass(frozen=True)
class ZmpReferenceParams:
    transition: ZmpTransition = ZmpTransition.LINEAR
    forward_offset_m: float = 0.0
    inward_offset_m: float = 0.0
    lab_move_s: float = 0.1  # LAB_SPLIT's t_double (the lab's 0.1 s)

    def __post_init__(self) -> None:
        if not isinstance(self.transition, ZmpTransition):
            raise FootstepPlanError(f"transition must be a ZmpTransition, got {self.transition!r}")
        for name in ("forward_offset_m", "inward_offset_m"):
            if not math.isfinite(getattr(self, name)):
                raise FootstepPlanError(f"{name} must be finite, got {getattr(self, name)}")
        if not (math.isfinite(self.lab_move_s) and self.lab_move_s > 0):
            raise FootstepPlanError(f"lab_move_s must be finite and > 0, got {self.lab_move_s}")


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
    middles: list[np.ndarray] = []  # between the feet on the ground in that segment
    # The ZMP target each segment ends at, in segment order (feet updated at touchdowns).
    for seg in timeline.segments:
        middles.append(midpoint())
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
    for seg, target, middle in zip(timeline.segments, targets, middles, strict=True):
        rows = slice(seg.start_tick, seg.end_tick)
        if seg.kind is not SegmentKind.DOUBLE_SUPPORT:
            reference[rows] = target
        elif params.transition is ZmpTransition.LAB_SPLIT:
            reference[rows] = _lab_split(current, middle, target, seg.n_ticks, timeline, params)
        else:
            s = np.arange(seg.n_ticks) / seg.n_ticks
            weight = params.transition.blend(s)[:, None]
            reference[rows] = (1.0 - weight) * current + weight * target
        current = target
    return reference


def _lab_split(
    start: np.ndarray,
    middle: np.ndarray,
    end: np.ndarray,
    n_ticks: int,
    timeline: WalkTimeline,
    params: ZmpReferenceParams,
) -> np.ndarray:
    """One double support of the lab's split (module docstring): start -> middle in the first
    n_move ticks, held, middle -> end in the last n_move ticks."""
    n_move = round(params.lab_move_s / timeline.dt_s)
    if n_move < 1 or 2 * n_move > n_ticks:
        raise FootstepPlanError(
            f"the lab's split needs two moves of lab_move_s = {params.lab_move_s} s (>= 1 tick "
            f"each) in the double support of {n_ticks * timeline.dt_s:.3f} s"
        )
    ramp = (np.arange(n_move) + 1.0)[:, None] / n_move
    rows = np.repeat(middle[None, :], n_ticks, axis=0)
    rows[:n_move] = start + ramp * (middle - start)
    rows[n_ticks - n_move :] = middle + ramp * (end - middle)
    return rows
