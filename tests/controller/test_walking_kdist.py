"""Kdist per leg by phase: the lab's landing-leg schedule at stated ticks."""

from __future__ import annotations

import numpy as np
import pytest

from controller.walking import (
    FootstepPlanError,
    KdistSchedule,
    SegmentKind,
    Side,
    StepTiming,
    WalkTimeline,
    kdist_gain,
    kdist_per_joint,
    straight_walk_plan,
)

DT = 0.005


def _gains(timeline: WalkTimeline, schedule: KdistSchedule) -> np.ndarray:
    return np.array(
        [
            [kdist_gain(side, timeline.phase(k), schedule) for side in Side]
            for k in range(timeline.n_ticks)
        ]
    )


def test_lab_timing_reproduces_the_lab_ticks():
    """The lab's master timing: step 240 ticks = rest 10, DSP 20, SSP 180, DSP 20, rest 10; its
    swing leg is 0.2 until tick 190, 1.0 at 210 (touchdown), holds to 230, 0.2 again at 240.
    Here: single support 0.9 s, double support 0.3 s, hold 0.1 s and release 0.05 s."""
    timing = StepTiming(0.9, 0.3, 1.6, 1.0)
    schedule = KdistSchedule(hold_after_touchdown_s=0.1, release_s=0.05)
    schedule.check_timing(timing)
    timeline = WalkTimeline(straight_walk_plan(3, 0.2, timing), DT)
    swing = timeline.segments[2]  # first single support, the right leg swings
    assert swing.kind is SegmentKind.SINGLE_SUPPORT and swing.landing_side is Side.RIGHT
    lab_ssp_start = 30  # the lab's tick numbers are offsets from its step start

    def right(lab_tick: int) -> float:
        tick = swing.start_tick + lab_tick - lab_ssp_start
        return kdist_gain(Side.RIGHT, timeline.phase(tick), schedule)

    def left(lab_tick: int) -> float:
        tick = swing.start_tick + lab_tick - lab_ssp_start
        return kdist_gain(Side.LEFT, timeline.phase(tick), schedule)

    assert right(30) == 0.2 and right(189) == 0.2
    assert right(190) == pytest.approx(0.2, abs=1e-12)
    assert right(200) == pytest.approx(0.6)  # cubic at half-way: 0.2 + 0.8 * 0.5
    assert right(195) == pytest.approx(0.2 + 0.8 * (3 * 0.25**2 - 2 * 0.25**3))
    assert right(210) == 1.0 and right(229) == 1.0 and right(230) == pytest.approx(1.0)
    assert right(235) == pytest.approx(0.6)
    assert right(240) == pytest.approx(0.2) and right(260) == 0.2
    assert all(left(t) == 0.2 for t in range(30, 270))  # the stance leg


def test_default_schedule_holds_through_the_double_support():
    timing = StepTiming(0.8, 3.2, 1.6, 1.0)  # the paper's slow walking
    schedule = KdistSchedule()
    schedule.check_timing(timing)
    timeline = WalkTimeline(straight_walk_plan(3, 0.2, timing), DT)
    gains = _gains(timeline, schedule)
    td = timeline.touchdown_ticks
    # Right leg lands first (footstep 0), then left, then right.
    assert gains[td[0] - 21, 1] == 0.2 and gains[td[0] - 10, 1] == pytest.approx(0.6)
    assert gains[td[0], 1] == 1.0
    ds_end = td[0] + 640  # the double support after the touchdown is 3.2 s
    assert np.all(gains[td[0] : ds_end - 10, 1] == 1.0)
    assert gains[ds_end - 5, 1] == pytest.approx(0.6)
    assert gains[ds_end, 1] == 0.2  # next single support: now the stance leg
    for index, side in ((0, Side.RIGHT), (1, Side.LEFT), (2, Side.RIGHT)):
        assert gains[td[index], side.index] == 1.0
        assert gains[td[index], side.other.index] == 0.2


def test_whole_walk_gains_stay_between_stance_and_landing_values():
    timing = StepTiming(0.8, 0.3, 1.6, 1.0)
    timeline = WalkTimeline(straight_walk_plan(6, 0.2, timing), DT)
    gains = _gains(timeline, KdistSchedule())
    assert gains.min() == 0.2 and gains.max() == 1.0
    assert np.all(gains[: timeline.liftoff_ticks[0]] == 0.2)  # rests and first weight shift
    assert np.all(gains[-200:] == 0.2)  # final rest
    assert np.all(gains.min(axis=1) == 0.2)  # never both legs raised at once


def test_check_timing_refuses_ramps_longer_than_their_phases():
    with pytest.raises(FootstepPlanError, match="ramp_up_s"):
        KdistSchedule(ramp_up_s=0.5).check_timing(StepTiming(0.4, 0.3, 1.6, 1.0))
    with pytest.raises(FootstepPlanError, match="hold"):
        KdistSchedule(hold_after_touchdown_s=0.3).check_timing(StepTiming(0.8, 0.3, 1.6, 1.0))
    with pytest.raises(ValueError, match="release_s"):
        KdistSchedule(release_s=0.0)


def test_per_joint_vector_repeats_each_legs_gain_over_its_six_joints():
    timeline = WalkTimeline(straight_walk_plan(2, 0.2, StepTiming(0.8, 0.3, 1.6, 1.0)), DT)
    touchdown = int(timeline.touchdown_ticks[0])  # the right leg has just landed
    gains = kdist_per_joint(timeline.phase(touchdown), KdistSchedule())
    assert gains.tolist() == [0.2] * 6 + [1.0] * 6


def test_the_labs_split_holds_for_dsp2_and_releases_over_rest_last():
    """On the lab's step split (walking_controller.cpp, 2018): 1.0 from the touchdown through
    DSP2 (t_double = 0.1 s), then a cubic back to the stance gain over rest_last, half of what
    the two 0.1 s moves leave of the double support: 0.05 s in the dynamic walk, 1.5 s in the
    slow one."""
    dynamic = KdistSchedule.lab_split(0.2, 0.3, 0.1)
    assert (dynamic.hold_after_touchdown_s, dynamic.release_s) == pytest.approx((0.1, 0.05))
    slow = KdistSchedule.lab_split(0.2, 3.2, 0.1)
    assert (slow.hold_after_touchdown_s, slow.release_s) == pytest.approx((0.1, 1.5))
    plan = straight_walk_plan(3, 0.2, StepTiming(0.8, 0.3, 1.6, 0.5))
    timeline = WalkTimeline(plan, DT)
    after = timeline.segments[3]  # the double support after the right foot's touchdown
    start = after.start_tick

    def right(ticks_after_touchdown: int) -> float:
        return kdist_gain(Side.RIGHT, timeline.phase(start + ticks_after_touchdown), dynamic)

    assert right(0) == right(19) == 1.0  # DSP2
    assert right(22) == pytest.approx(0.2 + 0.8 * (1 - (3 * 0.2**2 - 2 * 0.2**3)))  # s = 2/10
    assert right(30) == right(59) == 0.2  # released 0.15 s after the touchdown
    assert kdist_gain(Side.LEFT, timeline.phase(start + 5), dynamic) == 0.2
    with pytest.raises(FootstepPlanError, match="longer than 2 x"):
        KdistSchedule.lab_split(0.2, 0.2, 0.1)
