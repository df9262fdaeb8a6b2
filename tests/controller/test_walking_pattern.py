"""WalkingPattern: per-tick references consistent with the plan, cheap to read."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from controller.walking import (
    LegsGeometry,
    SegmentKind,
    Side,
    StepTiming,
    Support,
    WalkingParams,
    WalkingPattern,
    straight_walk_plan,
)

DYNAMIC = StepTiming(0.8, 0.3, 1.6, 1.0)
W = 0.127794


@pytest.fixture(scope="module")
def pattern() -> WalkingPattern:
    return WalkingPattern(straight_walk_plan(4, 0.2, DYNAMIC), legs=LegsGeometry.dyros_jet())


def test_shapes_and_read_only_arrays(pattern):
    n = pattern.n_ticks
    assert n == len(pattern) == round(pattern.plan.duration_s / 0.005)
    assert pattern.com_position_m.shape == (n, 3) and pattern.foot_position_m.shape == (n, 2, 3)
    assert pattern.joint_angles_rad.shape == (n, 12)
    with pytest.raises(ValueError):
        pattern.com_position_m[0, 0] = 1.0
    sample = pattern.sample(100)
    with pytest.raises(ValueError):
        sample.foot_position_m[0, 0] = 1.0


def test_sample_is_a_view_of_the_arrays(pattern):
    k = 1234
    s = pattern.sample(k)
    assert s.tick == k and s.time_s == pytest.approx(k * 0.005)
    assert np.array_equal(s.com_position_m, pattern.com_position_m[k])
    assert np.array_equal(s.foot_position_m, pattern.foot_position_m[k])
    assert np.array_equal(s.joint_angles_rad, pattern.joint_angles_rad[k])
    assert s.phase == pattern.timeline.phase(k)
    with pytest.raises(IndexError):
        pattern.sample(n := pattern.n_ticks)
    assert n > 0


def test_com_height_constant_and_pelvis_is_the_com_by_default(pattern):
    assert np.all(pattern.com_position_m[:, 2] == 0.8)
    assert np.all(pattern.com_velocity_mps[:, 2] == 0.0)
    assert np.array_equal(pattern.pelvis_position_m, pattern.com_position_m)


def test_pelvis_offset_turns_with_the_pelvis():
    params = WalkingParams(pelvis_offset_from_com_m=(-0.05, 0.0, 0.1))
    from controller.walking import Footstep, FootstepPlan

    yaw = math.pi / 2
    plan = FootstepPlan(
        Footstep(Side.LEFT, -W, 0.0, yaw),
        Footstep(Side.RIGHT, W, 0.0, yaw),
        (Footstep(Side.RIGHT, W, 0.2, yaw),),
        DYNAMIC,
    )
    pattern = WalkingPattern(plan, params)
    offset = pattern.pelvis_position_m - pattern.com_position_m
    assert np.allclose(offset, [0.0, -0.05, 0.1], atol=1e-12)  # x_pelvis -0.05 -> world -y


def test_feet_are_planted_except_the_swing_foot_in_its_single_support(pattern):
    plan, timeline = pattern.plan, pattern.timeline
    ankle = 0.105
    for seg in timeline.segments:
        rows = slice(seg.start_tick, seg.end_tick)
        for side in Side:
            feet = pattern.foot_position_m[rows, side.index]
            swinging = seg.kind is SegmentKind.SINGLE_SUPPORT and seg.landing_side is side
            if swinging:
                assert feet[:, 2].max() == pytest.approx(ankle + 0.05)
            else:
                assert np.all(feet == feet[0]) and feet[0, 2] == ankle
                assert np.all(pattern.foot_velocity_mps[rows, side.index] == 0.0)
    for i, step in enumerate(plan.footsteps):  # each foot is on its footstep at touchdown
        at = pattern.foot_position_m[timeline.touchdown_ticks[i], step.side.index]
        assert at == pytest.approx([step.x_m, step.y_m, ankle], abs=1e-15)


def test_zmp_reference_sits_on_the_stance_foot_in_single_support(pattern):
    for seg in pattern.timeline.segments:
        if seg.kind is not SegmentKind.SINGLE_SUPPORT:
            continue
        stance = Side.LEFT if seg.support is Support.LEFT else Side.RIGHT
        rows = slice(seg.start_tick, seg.end_tick)
        assert np.allclose(
            pattern.zmp_reference_m[rows],
            pattern.foot_position_m[rows, stance.index, :2],
            atol=1e-15,
        )


def test_com_sways_towards_the_stance_foot_and_ends_between_the_feet(pattern):
    timeline = pattern.timeline
    first_ss = timeline.segments[2]  # left stance (right swings first)
    middle = (first_ss.start_tick + first_ss.end_tick) // 2
    assert 0.0 < pattern.com_position_m[middle, 1] < W
    assert pattern.com_position_m[-1, :2] == pytest.approx([0.6, 0.0], abs=2e-3)
    assert np.abs(pattern.com_velocity_mps[-1]).max() < 0.02


def test_per_tick_read_is_cheap(pattern):
    n = pattern.n_ticks
    start = time.perf_counter()
    for k in range(n):
        pattern.sample(k)
    per_tick_s = (time.perf_counter() - start) / n
    assert per_tick_s < 200e-6, f"{per_tick_s * 1e6:.1f} us per sample"  # measured ~11 us


def test_construction_time_of_a_slow_walk():
    start = time.perf_counter()
    WalkingPattern(
        straight_walk_plan(6, 0.2, StepTiming(0.8, 3.2, 1.6, 1.0)), legs=LegsGeometry.dyros_jet()
    )
    assert time.perf_counter() - start < 5.0  # measured ~0.65 s for 5960 ticks


def test_the_labs_swing_guard_keeps_the_swing_foot_down_at_both_ends_of_its_single_support():
    """swing_guard_s (the lab's t_rest_temp, 0.1 s): the foot stays at its lift-off place for
    the first 0.1 s of the single support, is at its footstep from 0.1 s before its end, and
    reaches the apex at mid single support; the swing in between is the quintic over 0.6 s."""
    guarded = WalkingPattern(straight_walk_plan(2, 0.2, DYNAMIC), WalkingParams(swing_guard_s=0.1))
    single = next(s for s in guarded.timeline.segments if s.kind is SegmentKind.SINGLE_SUPPORT)
    side = single.landing_side.index
    start, end = single.start_tick, single.start_tick + single.n_ticks
    feet = guarded.foot_position_m[:, side]
    assert np.array_equal(feet[start : start + 20], np.repeat(feet[start - 1 : start], 20, axis=0))
    target = guarded.plan.footsteps[single.footstep_index]
    assert np.allclose(feet[end - 20 : end, :2], [target.x_m, target.y_m], atol=1e-12)
    ankle = guarded.params.ankle_height_m
    assert np.allclose(feet[end - 20 : end, 2], ankle, atol=1e-12)
    assert feet[start + 80, 2] == pytest.approx(ankle + guarded.params.swing_height_m)
    # the airborne part is the quintic over 0.6 s: a quarter of the way, s = 0.25 of 0.6 s
    quarter = feet[start + 20 + 30, 0] - feet[start, 0]
    s = 0.25
    blend = s**3 * (10 - 15 * s + 6 * s * s)
    assert quarter == pytest.approx((target.x_m - feet[start, 0]) * blend)
    with pytest.raises(ValueError, match="swing_guard_s"):
        WalkingPattern(straight_walk_plan(2, 0.2, DYNAMIC), WalkingParams(swing_guard_s=0.4))


def test_the_preview_height_sets_the_cart_tables_zc_alone():
    """preview_height_m (the lab's zc above the ankle): the preview designs on it, the planned
    CoM stays at com_height_m, and the CoM swings wider on the lower cart-table."""
    plan = straight_walk_plan(2, 0.2, DYNAMIC)
    plain = WalkingPattern(plan, WalkingParams(com_height_m=0.8))
    lower = WalkingPattern(plan, WalkingParams(com_height_m=0.8, preview_height_m=0.7))
    assert lower.preview_gains.model.com_height_m == 0.7
    assert np.all(lower.com_position_m[:, 2] == 0.8)
    assert np.abs(lower.com_position_m[:, 1]).max() > np.abs(plain.com_position_m[:, 1]).max()
