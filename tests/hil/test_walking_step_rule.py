"""The walking metrics' step rule (hil/experiments/walking.py, `steps_completed`): a footstep
counts when its foot left the ground in its swing (lifted), then carried at least LANDED_SHARE
of the weight in the double support after its touchdown (loaded), the log covers that double
support (covered), and the robot had not fallen by its end (standing).

Each condition is tested alone on a synthetic walk (the feet's vertical forces as the foot
sensors would report them, on the experiment's own timeline): a walk in which every step is
taken but that one condition fails at the second or third step. So a rule that lost any one
condition counts steps it should not, and fails here - for "loaded" that is a walk in which the
landing foot lifts and comes down but never takes the weight while the robot stays up."""

from __future__ import annotations

import numpy as np
import pytest

from controller.walking import SegmentKind
from hil.experiments.walking import WALK_DYNAMIC
from hil.experiments.walking_kinematics import (
    CONTACT_SHARE,
    FALL_TILT_RAD,
    LANDED_SHARE,
    WalkingKinematics,
)

EXPERIMENT = WALK_DYNAMIC
WEIGHT_N = 500.0
DT = EXPERIMENT.pattern.dt_s


def _steps() -> list:
    """The single supports of the footsteps, in order (the swing of each)."""
    return [
        s
        for s in EXPERIMENT.pattern.timeline.segments
        if s.kind is SegmentKind.SINGLE_SUPPORT and s.footstep_index is not None
    ]


def _landing(step) -> object:
    segments = EXPERIMENT.pattern.timeline.segments
    return segments[segments.index(step) + 1]  # the double support after its touchdown


def _walk(end_s: float | None = None) -> dict[str, np.ndarray]:
    """A walk that takes every step: both feet share the weight in double support, the stance
    foot carries it in single support while the swing foot is off the ground."""
    end = EXPERIMENT.pattern.n_ticks * DT if end_s is None else end_s
    time = np.arange(0.0, end - DT / 2, DT)
    vertical = np.full((time.size, 2), WEIGHT_N / 2)
    for step in _steps():
        swing = (time >= step.start_tick * DT) & (time < step.end_tick * DT)
        side = step.landing_side.index
        vertical[swing, side] = 0.0
        vertical[swing, 1 - side] = WEIGHT_N
    return {"time": time, "vertical": vertical, "tilt": np.zeros(time.size)}


def _kinematics(walk: dict[str, np.ndarray]) -> WalkingKinematics:
    n = walk["time"].size
    return WalkingKinematics(
        rows=np.arange(n),
        time_s=walk["time"],
        zmp_m=np.zeros((n, 2)),
        desired_zmp_m=np.zeros((n, 2)),
        vertical_n=walk["vertical"],
        tilt_rad=walk["tilt"],
        com_m=np.zeros((n, 3)),
        sole_centre_m=np.zeros((n, 2, 3)),
        sole_yaw_rad=np.zeros((n, 2)),
        margin_m=np.full(n, 0.05),  # the ZMP well inside the support polygon throughout
        links_rad=np.zeros((n, 12)),
        weight_n=WEIGHT_N,
        period_s=DT,
    )


def _count(walk: dict[str, np.ndarray]) -> tuple[int, float | None]:
    kinematics = _kinematics(walk)
    fell_at = kinematics.fall_time_s()
    return kinematics.steps_completed(EXPERIMENT, fell_at), fell_at


def _rows(walk: dict[str, np.ndarray], segment) -> np.ndarray:
    time = walk["time"]
    return (time >= segment.start_tick * DT) & (time < segment.end_tick * DT)


def test_a_walk_that_takes_every_step_counts_them_all() -> None:
    assert len(_steps()) == EXPERIMENT.n_steps == 4
    assert _count(_walk()) == (4, None)


def test_loaded_a_landing_foot_that_comes_down_but_never_takes_the_weight() -> None:
    walk = _walk()
    second = _steps()[1]
    side = second.landing_side.index
    landed = _rows(walk, _landing(second))
    # in contact (above CONTACT_SHARE), never loaded (below LANDED_SHARE); the other foot
    # carries the rest: the robot stays up
    touch = 0.5 * (CONTACT_SHARE + LANDED_SHARE) * WEIGHT_N
    walk["vertical"][landed, side] = touch
    walk["vertical"][landed, 1 - side] = WEIGHT_N - touch
    count, fell_at = _count(walk)
    assert fell_at is None  # it did not fall
    assert count == 1  # the first step; the second was never loaded


def test_lifted_a_swing_foot_that_never_leaves_the_ground() -> None:
    walk = _walk()
    second = _steps()[1]
    walk["vertical"][_rows(walk, second)] = WEIGHT_N / 2  # both feet down through the swing
    count, fell_at = _count(walk)
    assert fell_at is None
    assert count == 1


def test_covered_a_log_that_ends_before_the_landing_double_support_ends() -> None:
    third = _steps()[2]
    landing = _landing(third)
    # the log ends a few ticks into the third step's landing: the foot is down and loaded,
    # but the double support is not over
    walk = _walk(end_s=(landing.start_tick + 5) * DT)
    count, fell_at = _count(walk)
    assert fell_at is None
    assert count == 2


def test_standing_a_robot_that_fell_before_the_step_was_done() -> None:
    walk = _walk()
    third = _steps()[2]
    tipping = walk["time"] >= (third.start_tick + 10) * DT
    walk["tilt"][tipping] = FALL_TILT_RAD + 0.1  # the feet's forces stay as in a good walk
    count, fell_at = _count(walk)
    assert fell_at == pytest.approx((third.start_tick + 10) * DT)
    assert count == 2
