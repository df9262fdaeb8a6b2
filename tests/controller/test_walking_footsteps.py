"""Footstep plan and its timeline on the tick grid: positions, validation, phase per tick."""

from __future__ import annotations

import math

import pytest

from controller.walking import (
    Footstep,
    FootstepPlan,
    FootstepPlanError,
    SegmentKind,
    Side,
    StepTiming,
    Support,
    WalkTimeline,
    straight_walk_plan,
)

DT = 0.005
SLOW = StepTiming(single_support_s=0.8, double_support_s=3.2, initial_rest_s=1.6, final_rest_s=1.0)
DYNAMIC = StepTiming(0.8, 0.3, 1.6, 1.0)


def test_straight_walk_places_alternating_footsteps_and_closes_the_stance():
    plan = straight_walk_plan(4, 0.2, DYNAMIC)
    w = 0.127794  # the lab's nominal lateral foot offset
    assert plan.initial_left == Footstep(Side.LEFT, 0.0, w)
    assert plan.initial_right == Footstep(Side.RIGHT, 0.0, -w)
    expected = [
        (Side.RIGHT, 0.2, -w),
        (Side.LEFT, 0.4, w),
        (Side.RIGHT, 0.6, -w),
        (Side.LEFT, 0.6, w),
    ]
    got = [(s.side, s.x_m, s.y_m) for s in plan.footsteps]
    assert [g[0] for g in got] == [e[0] for e in expected]
    for (_, x, y), (_, ex, ey) in zip(got, expected, strict=True):
        assert x == pytest.approx(ex) and y == pytest.approx(ey)
    left, right = plan.final_stance()
    assert left.x_m == pytest.approx(right.x_m) == pytest.approx(0.6)


def test_first_swing_and_width_are_parameters():
    plan = straight_walk_plan(2, 0.1, DYNAMIC, lateral_foot_offset_m=0.15, first_swing=Side.LEFT)
    assert plan.footsteps[0] == Footstep(Side.LEFT, 0.1, 0.15)
    assert plan.footsteps[1] == Footstep(Side.RIGHT, 0.1, -0.15)


def test_plan_duration_adds_up():
    plan = straight_walk_plan(5, 0.2, SLOW)
    assert plan.duration_s == pytest.approx(1.6 + 5 * (3.2 + 0.8) + 3.2 + 1.0)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"n_steps": 0}, "n_steps"),
        ({"step_length_m": math.nan}, "step_length_m"),
        ({"lateral_foot_offset_m": -0.1}, "lateral_foot_offset_m"),
        ({"lateral_foot_offset_m": 0.05}, "min_lateral_separation_m"),  # 0.10 m < foot width
    ],
)
def test_straight_walk_rejects_bad_arguments(kwargs, message):
    arguments = {"n_steps": 3, "step_length_m": 0.2, "timing": DYNAMIC} | kwargs
    with pytest.raises(FootstepPlanError, match=message):
        straight_walk_plan(**arguments)


@pytest.mark.parametrize("field", ["single_support_s", "double_support_s", "initial_rest_s"])
@pytest.mark.parametrize("value", [0.0, -1.0, math.inf])
def test_timing_rejects_non_positive_durations(field, value):
    values = {
        "single_support_s": 0.8,
        "double_support_s": 0.3,
        "initial_rest_s": 1.6,
        "final_rest_s": 1.0,
    } | {field: value}
    with pytest.raises(FootstepPlanError, match=field):
        StepTiming(**values)


def test_plan_rejects_crossing_feet_and_wrong_sides():
    left, right = Footstep(Side.LEFT, 0, 0.13), Footstep(Side.RIGHT, 0, -0.13)
    with pytest.raises(FootstepPlanError, match="after footstep 0"):
        FootstepPlan(left, right, (Footstep(Side.RIGHT, 0.2, 0.05),), DYNAMIC)
    with pytest.raises(FootstepPlanError, match="initial_left"):
        FootstepPlan(right, right, (Footstep(Side.RIGHT, 0.2, -0.13),), DYNAMIC)
    with pytest.raises(FootstepPlanError, match="at least one footstep"):
        FootstepPlan(left, right, (), DYNAMIC)
    with pytest.raises(FootstepPlanError, match="yaw_rad"):
        Footstep(Side.LEFT, 0.0, 0.1, yaw_rad=4.0)


def test_separation_is_measured_in_the_feet_frames():
    # Feet 0.26 m apart in world y, both turned 90 degrees (facing +y): in their own frames
    # they stand one in front of the other, with no lateral gap at all.
    left = Footstep(Side.LEFT, 0.0, 0.13, yaw_rad=math.pi / 2)
    right = Footstep(Side.RIGHT, 0.0, -0.13, yaw_rad=math.pi / 2)
    with pytest.raises(FootstepPlanError, match="initial stance"):
        FootstepPlan(left, right, (Footstep(Side.RIGHT, 0.0, -0.13),), DYNAMIC)


def test_timeline_segments_and_touchdown_times():
    plan = straight_walk_plan(3, 0.2, DYNAMIC)
    timeline = WalkTimeline(plan, DT)
    kinds = [s.kind for s in timeline.segments]
    assert kinds == [SegmentKind.INITIAL_REST] + [
        SegmentKind.DOUBLE_SUPPORT,
        SegmentKind.SINGLE_SUPPORT,
    ] * 3 + [SegmentKind.DOUBLE_SUPPORT, SegmentKind.FINAL_REST]
    assert timeline.n_ticks == round(plan.duration_s / DT) == 320 + 3 * (60 + 160) + 60 + 200
    for i in range(3):  # lift-off i = rest + (i+1) DS + i SS; touchdown = lift-off + SS
        assert timeline.liftoff_times_s[i] == pytest.approx(1.6 + (i + 1) * 0.3 + i * 0.8)
        assert timeline.touchdown_times_s[i] == pytest.approx(1.6 + (i + 1) * 1.1)


def test_phase_signal_per_tick():
    plan = straight_walk_plan(3, 0.2, DYNAMIC)  # right foot swings first
    timeline = WalkTimeline(plan, DT)
    rest = timeline.phase(0)
    assert (rest.kind, rest.support, rest.landing_side) == (
        SegmentKind.INITIAL_REST,
        Support.DOUBLE,
        None,
    )
    first_ds = timeline.phase(320 + 10)
    assert first_ds.support is Support.DOUBLE and first_ds.landing_side is None
    assert first_ds.time_in_phase_s == pytest.approx(0.05)
    swing = timeline.phase(320 + 60 + 100)  # 0.5 s into the first single support
    assert swing.support is Support.LEFT and swing.landing_side is Side.RIGHT
    assert swing.time_in_phase_s == pytest.approx(0.5)
    assert swing.phase_duration_s == pytest.approx(0.8)
    assert swing.touchdown_time_s == pytest.approx(2.7)
    after = timeline.phase(320 + 60 + 160)  # the nominal touchdown tick
    assert after.kind is SegmentKind.DOUBLE_SUPPORT and after.landing_side is Side.RIGHT
    assert after.time_in_phase_s == 0.0 and after.touchdown_time_s == pytest.approx(2.7)
    second = timeline.phase(320 + 2 * 60 + 160 + 1)
    assert second.support is Support.RIGHT and second.landing_side is Side.LEFT
    assert second.footstep_index == 1
    end = timeline.phase(timeline.n_ticks - 1)
    assert end.kind is SegmentKind.FINAL_REST and end.landing_side is None


def test_timeline_rejects_durations_off_the_tick_grid():
    with pytest.raises(FootstepPlanError, match="single_support_s"):
        WalkTimeline(straight_walk_plan(2, 0.2, StepTiming(0.8023, 0.3, 1.6, 1.0)), DT)
