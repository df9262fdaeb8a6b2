"""Footstep plan: where each foot lands and when, on flat ground.

A plan is the two feet's initial placements, the ordered footsteps (one per swing: which foot
swings and where it lands) and the timing. The timeline it implies (see `timeline.py`):

    initial rest (double support, ZMP between the feet)
    per footstep i: double support (ZMP moves onto the stance foot), single support (the other
                    foot swings to footstep i and touches down at the end)
    final double support (ZMP back between the feet), final rest.

So two consecutive single supports are separated by exactly one double support; Kim et al.,
ICRA 2018, Sec. IV-C walk with 0.8 s single / 3.2 s double support ("slow") and 0.8 s / 0.3 s
("dynamic"). Positions are the ground projection of each foot's ankle frame (x, y) [m] and its
yaw [rad] about the vertical.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

from controller.walking.dyros_jet_figures import FOOT_WIDTH_M, NOMINAL_LATERAL_FOOT_OFFSET_M


class FootstepPlanError(ValueError):
    """A footstep plan or its timing is not usable; the message says which value and why."""


class Side(Enum):
    """A foot (or leg). `lateral_sign` is +1 for the left (+y), -1 for the right."""

    LEFT = "left"
    RIGHT = "right"

    @property
    def lateral_sign(self) -> int:
        return 1 if self is Side.LEFT else -1

    @property
    def other(self) -> Side:
        return Side.RIGHT if self is Side.LEFT else Side.LEFT

    @property
    def index(self) -> int:
        """0 for the left, 1 for the right: the order of per-foot arrays and of the legs' joints."""
        return 0 if self is Side.LEFT else 1


@dataclass(frozen=True)
class Footstep:
    """A foot placement on flat ground: the ankle frame's ground projection and yaw."""

    side: Side
    x_m: float
    y_m: float
    yaw_rad: float = 0.0

    def __post_init__(self) -> None:
        if not isinstance(self.side, Side):
            raise FootstepPlanError(f"footstep side must be a Side, got {self.side!r}")
        for name in ("x_m", "y_m", "yaw_rad"):
            value = getattr(self, name)
            if not math.isfinite(value):
                raise FootstepPlanError(f"footstep {name} must be finite, got {value}")
        if abs(self.yaw_rad) > math.pi:
            raise FootstepPlanError(f"footstep yaw_rad must be in [-pi, pi], got {self.yaw_rad}")


@dataclass(frozen=True)
class StepTiming:
    """Durations [s]: single support (a swing), double support (between swings), rests.

    initial_rest_s must be at least the preview horizon of the ZMP preview controller (checked
    where the horizon is known); final_rest_s > 0 lets the CoM settle over the final stance.
    """

    single_support_s: float
    double_support_s: float
    initial_rest_s: float
    final_rest_s: float

    def __post_init__(self) -> None:
        for name in ("single_support_s", "double_support_s", "initial_rest_s", "final_rest_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise FootstepPlanError(f"timing {name} must be finite and > 0, got {value}")


@dataclass(frozen=True)
class FootstepPlan:
    """Initial feet, footsteps in order (one per swing) and timing.

    Checked at construction: the initial feet are a left and a right foot; at least one
    footstep; wherever both feet stand, the left foot is at least `min_lateral_separation_m` to
    the left of the right foot, measured in either foot's frame (default: one foot width, 0.17 m,
    so that the soles do not overlap side by side).
    """

    initial_left: Footstep
    initial_right: Footstep
    footsteps: tuple[Footstep, ...]
    timing: StepTiming
    min_lateral_separation_m: float = FOOT_WIDTH_M

    def __post_init__(self) -> None:
        if self.initial_left.side is not Side.LEFT:
            raise FootstepPlanError("initial_left must be a LEFT footstep")
        if self.initial_right.side is not Side.RIGHT:
            raise FootstepPlanError("initial_right must be a RIGHT footstep")
        if not isinstance(self.footsteps, tuple):
            object.__setattr__(self, "footsteps", tuple(self.footsteps))
        if len(self.footsteps) == 0:
            raise FootstepPlanError("a plan needs at least one footstep")
        if not (
            math.isfinite(self.min_lateral_separation_m) and self.min_lateral_separation_m >= 0
        ):
            raise FootstepPlanError(
                f"min_lateral_separation_m must be finite and >= 0, got "
                f"{self.min_lateral_separation_m}"
            )
        for index, (left, right) in enumerate(self.stances()):
            separation = min(
                _left_of_right(left, right, frame=left), _left_of_right(left, right, frame=right)
            )
            if separation < self.min_lateral_separation_m:
                where = "initial stance" if index == 0 else f"after footstep {index - 1}"
                raise FootstepPlanError(
                    f"{where}: the left foot is {separation:.4f} m to the left of the right "
                    f"foot, less than min_lateral_separation_m = {self.min_lateral_separation_m} m "
                    f"(feet would overlap or cross)"
                )

    def stances(self) -> list[tuple[Footstep, Footstep]]:
        """(left, right) placements: initially, then after each footstep's touchdown."""
        left, right = self.initial_left, self.initial_right
        result = [(left, right)]
        for step in self.footsteps:
            if step.side is Side.LEFT:
                left = step
            else:
                right = step
            result.append((left, right))
        return result

    def final_stance(self) -> tuple[Footstep, Footstep]:
        return self.stances()[-1]

    @property
    def duration_s(self) -> float:
        t = self.timing
        swings = len(self.footsteps) * (t.double_support_s + t.single_support_s)
        return t.initial_rest_s + swings + t.double_support_s + t.final_rest_s


def _left_of_right(left: Footstep, right: Footstep, frame: Footstep) -> float:
    """How far the left foot is to the left of the right foot [m]: the y component of
    (left - right) expressed in `frame`'s yaw."""
    dx, dy = left.x_m - right.x_m, left.y_m - right.y_m
    return -math.sin(frame.yaw_rad) * dx + math.cos(frame.yaw_rad) * dy


def straight_walk_plan(
    n_steps: int,
    step_length_m: float,
    timing: StepTiming,
    lateral_foot_offset_m: float = NOMINAL_LATERAL_FOOT_OFFSET_M,
    first_swing: Side = Side.RIGHT,
) -> FootstepPlan:
    """A straight walk along +x from feet side by side at x = 0, y = +-lateral_foot_offset_m.

    Footstep i (i < n_steps - 1) of the swinging foot lands at x = (i + 1) * step_length_m (so
    the feet are step_length_m apart in x, and a middle swing travels 2 * step_length_m); the
    last footstep closes the stance beside the other foot. The walk advances
    (n_steps - 1) * step_length_m. Defaults as the lab's planner: the right foot swings first,
    feet 0.127794 m either side of the walking line (step width 0.255588 m).
    """
    if not (isinstance(n_steps, int) and n_steps >= 1):
        raise FootstepPlanError(f"n_steps must be an int >= 1, got {n_steps!r}")
    if not math.isfinite(step_length_m):
        raise FootstepPlanError(f"step_length_m must be finite, got {step_length_m}")
    if not (math.isfinite(lateral_foot_offset_m) and lateral_foot_offset_m > 0):
        raise FootstepPlanError(
            f"lateral_foot_offset_m must be finite and > 0, got {lateral_foot_offset_m}"
        )
    if not isinstance(first_swing, Side):
        raise FootstepPlanError(f"first_swing must be a Side, got {first_swing!r}")
    w = lateral_foot_offset_m
    steps: list[Footstep] = []
    side = first_swing
    for i in range(n_steps):
        x = (i + 1) * step_length_m if i < n_steps - 1 else (n_steps - 1) * step_length_m
        steps.append(Footstep(side, x, side.lateral_sign * w))
        side = side.other
    return FootstepPlan(
        initial_left=Footstep(Side.LEFT, 0.0, w),
        initial_right=Footstep(Side.RIGHT, 0.0, -w),
        footsteps=tuple(steps),
        timing=timing,
    )
