"""The lab's walking terms (controller/walking/lab_terms.py) against hand computations, and the
deflection model's sign against the lab's own formula (psh117/dyros_jet walking_controller.cpp,
`hipCompensation`: its knee rows of the hand-derived Jacobians, ported here as the test's
reference)."""

from __future__ import annotations

import math
from math import cos, sin
from pathlib import Path

import numpy as np
import pytest

from controller.humanoid import (
    WALKING_READY_LEG_ANGLES_RAD,
    HumanoidLegGravity,
    LegModel,
    SupportState,
)
from controller.walking import (
    CenterOfMassFeedback,
    CenterOfMassMeasurement,
    CenterOfMassStabiliser,
    DeflectionModel,
    Side,
    StepTiming,
    SupportHipRollOffsets,
    WalkTimeline,
    straight_walk_plan,
)

URDF = Path(__file__).resolve().parents[2] / "hil" / "data" / "robots" / "dyros_jet.urdf"


def test_com_feedback_adds_kp_times_the_error_and_caps_the_correction() -> None:
    feedback = CenterOfMassFeedback(0.15, 0.05)
    new = feedback.update(np.array([0.001, -0.002]), [0.10, 0.02, 0.8], [0.09, 0.03, 0.7])
    assert new == pytest.approx([0.001 + 0.15 * 0.01, -0.002 - 0.15 * 0.01])
    # a long error: the correction's length stops at the bound, its direction kept
    capped = feedback.update(np.array([0.03, 0.03]), [1.0, 1.0], [0.0, 0.0])
    assert math.hypot(*capped) == pytest.approx(0.05)
    assert capped[0] == pytest.approx(capped[1])
    # an integrator: a constant error of 1 cm ramps it by 1.5 mm a tick
    correction = np.zeros(2)
    for _ in range(10):
        correction = feedback.update(correction, [0.01, 0.0], [0.0, 0.0])
    assert correction == pytest.approx([0.015, 0.0])
    with pytest.raises(ValueError):
        CenterOfMassFeedback(0.0)


def test_the_2018_form_is_the_measured_pelvis_plus_kp_times_the_error() -> None:
    """The lab's May-June 2018 form, pelvis = pelvis measured + kp (c_desired - c_measured),
    returned as its offset from the plan's pelvis, by hand: no memory, the cap kept; a sway s
    that moves pelvis and CoM alike leaves (1 - kp) s."""
    feedback = CenterOfMassFeedback(1.0, 0.05, CenterOfMassMeasurement.MEASURED_PELVIS)
    assert not feedback.integrates
    plan = np.array([0.10, 0.02, 0.80])
    offset = feedback.measured_pelvis_correction(
        plan, [0.11, 0.01, 0.79], [0.12, 0.05, 0.7], [0.125, 0.045, 0.69]
    )
    assert offset == pytest.approx([0.11 - 0.005 - 0.10, 0.01 + 0.005 - 0.02])
    sway = np.array([0.0, 0.02, 0.0])
    for kp in (1.0, 0.9):
        feedback = CenterOfMassFeedback(kp, 0.05, CenterOfMassMeasurement.MEASURED_PELVIS)
        com = plan + np.array([0.01, 0.0, -0.1])  # the plan's CoM hangs 1 cm ahead, 10 cm low
        offset = feedback.measured_pelvis_correction(plan, plan + sway, com, com + sway)
        assert offset == pytest.approx((1.0 - kp) * sway[:2], abs=1e-15)
    far = feedback.measured_pelvis_correction(plan, plan + 1.0, com, com)
    assert math.hypot(*far) == pytest.approx(0.05)


def test_the_com_stabiliser_is_a_pd_on_the_measured_error() -> None:
    """Ours: -(gain e + damping e'), e' the error's difference low-passed at the cut-off. A
    constant error: -gain e from the first tick (no rate); an error growing at r: the rate's
    filter converges to r, so -(gain e + damping r); the correction's length is capped."""
    stabiliser = CenterOfMassStabiliser(gain=1.0, damping_s=0.2, velocity_cutoff_hz=10.0)
    state = stabiliser.tracker(0.005)
    assert state.correction([0.01, 0.0, 0.8], [0.0, 0.0, 0.8]) == pytest.approx([-0.01, 0.0])
    rate = np.array([0.0, 0.02])  # m/s
    state = stabiliser.tracker(0.005)
    for k in range(200):
        error = rate * 0.005 * k
        correction = state.correction(error, [0.0, 0.0])
    assert state.error_rate == pytest.approx(rate, rel=1e-9)
    assert correction == pytest.approx(-(error + 0.2 * rate), rel=1e-9)
    pole = math.exp(-2 * math.pi * 10.0 * 0.005)  # one tick of the filter, by hand
    state = stabiliser.tracker(0.005)
    state.correction([0.0, 0.0], [0.0, 0.0])
    step = state.correction([0.0, 0.001], [0.0, 0.0])
    assert step[1] == pytest.approx(-(0.001 + 0.2 * (1 - pole) * 0.001 / 0.005))
    capped = stabiliser.tracker(0.005).correction([1.0, 1.0], [0.0, 0.0])
    assert math.hypot(*capped) == pytest.approx(0.05)
    with pytest.raises(ValueError):
        CenterOfMassStabiliser(gain=-1.0)


def test_deflection_model_by_hand() -> None:
    """gain (a tau_lab + b), tau_lab = -tau_g: hip pitch 0.2, knee 0.3; the ankle pitch b alone."""
    tau = np.zeros(12)
    tau[[2, 3, 4, 8, 9, 10]] = [10.0, -30.0, 7.0, -4.0, 32.0, -3.0]
    offsets = DeflectionModel().offsets(tau)
    expected = np.zeros(12)
    expected[2] = 0.2 * (-0.0012 * -10.0 + 0.000874)
    expected[3] = 0.3 * (-0.0012 * 30.0 + 0.000874)
    expected[4] = 0.2 * 0.000874
    expected[8] = 0.2 * (-0.0012 * 4.0 + 0.000874)
    expected[9] = 0.3 * (-0.0012 * -32.0 + 0.000874)
    expected[10] = 0.2 * 0.000874
    assert offsets == pytest.approx(expected, abs=1e-15)


def _lab_knee_torques(q: np.ndarray) -> tuple[float, float]:
    """The lab's hipCompensation at these angles: the force split alpha from the pelvis, the
    weight 46.892 kg, the knee rows Jc8(3) (left) and Jc2(3) (right); (left, right) [N m]."""
    lq0, lq1, lq2, lq3 = q[:4]
    rq0, rq1, rq2, rq3 = q[6:10]
    from_right = (
        cos(rq2) * sin(rq0) * -0.1454
        - sin(rq0) * sin(rq2) * 0.339
        - cos(rq3) * (cos(rq2) * sin(rq0) + cos(rq0) * sin(rq1) * sin(rq2)) * 0.06
        - cos(rq3) * (sin(rq0) * sin(rq2) - cos(rq0) * cos(rq2) * sin(rq1)) * 0.368
        - sin(rq3) * (cos(rq2) * sin(rq0) + cos(rq0) * sin(rq1) * sin(rq2)) * 0.368
        + sin(rq3) * (sin(rq0) * sin(rq2) - cos(rq0) * cos(rq2) * sin(rq1)) * 0.06
        + cos(rq0) * cos(rq2) * sin(rq1) * 0.339
        - cos(rq0) * sin(rq1) * sin(rq2) * 0.1454
        - 0.105
    )
    from_left = (
        cos(lq2) * sin(lq0) * -0.1454
        + sin(lq0) * sin(lq2) * 0.339
        + cos(lq3) * (sin(lq0) * sin(lq2) + cos(lq0) * cos(lq2) * sin(lq1)) * 0.368
        - cos(lq3) * (cos(lq2) * sin(lq0) - cos(lq0) * sin(lq1) * sin(lq2)) * 0.06
        + sin(lq3) * (sin(lq0) * sin(lq2) + cos(lq0) * cos(lq2) * sin(lq1)) * 0.06
        + sin(lq3) * (cos(lq2) * sin(lq0) - cos(lq0) * sin(lq1) * sin(lq2)) * 0.368
        + cos(lq0) * cos(lq2) * sin(lq1) * 0.339
        + cos(lq0) * sin(lq1) * sin(lq2) * 0.1454
        + 0.105
    )
    alpha = -from_left / (from_right - from_left)
    weight = 46.892 * 9.81
    right = (
        cos(rq1) * cos(rq2) * cos(rq3) * 0.06
        + cos(rq1) * cos(rq2) * sin(rq3) * 0.368
        + cos(rq1) * cos(rq3) * sin(rq2) * 0.368
        - cos(rq1) * sin(rq2) * sin(rq3) * 0.06
    )
    left = (
        cos(lq1) * cos(lq2) * cos(lq3) * -0.06
        + cos(lq1) * cos(lq2) * sin(lq3) * 0.368
        + cos(lq1) * cos(lq3) * sin(lq2) * 0.368
        + cos(lq1) * sin(lq2) * sin(lq3) * 0.06
    )
    return left * weight * (1 - alpha), right * weight * alpha


def test_the_lab_torque_is_minus_the_gravity_compensators() -> None:
    """At the walking-ready posture (double support) the lab's knee torques carry the opposite
    sign of (5)'s and about its size (the lab's: the whole 46.9 kg at the pelvis, no leg
    masses): so the lab's a tau_lab is -a tau_g here, and the knee is bent further (the
    same direction as the gravity compensator's C tau_g)."""
    q = np.asarray(WALKING_READY_LEG_ANGLES_RAD)
    lab_left, lab_right = _lab_knee_torques(q)
    tau = HumanoidLegGravity(LegModel(URDF.read_text()), SupportState.DOUBLE).gravity_torque(q)
    for lab, ours in ((lab_left, tau[3]), (lab_right, tau[9])):
        assert lab * ours < 0
        assert 0.8 < abs(lab / ours) < 1.4
    offsets = DeflectionModel().offsets(tau)
    assert np.sign(offsets[3]) == np.sign(tau[3]) and np.sign(offsets[9]) == np.sign(tau[9])


def test_support_hip_roll_offsets_ramp_on_the_stance_hip() -> None:
    timing = StepTiming(0.8, 0.3, 1.6, 0.5)
    timeline = WalkTimeline(straight_walk_plan(2, 0.2, timing), 0.005)
    table = SupportHipRollOffsets().table(timeline)
    left, right = math.radians(4.0), -math.radians(8.5)
    singles = [s for s in timeline.segments if s.kind.value == "single_support"]
    assert [s.landing_side for s in singles] == [Side.RIGHT, Side.LEFT]  # stance L, then R
    for segment, joint, peak in ((singles[0], 1, left), (singles[1], 7, right)):
        start, end = segment.start_tick, segment.end_tick
        middle = (start + end) // 2
        assert table[middle, joint] == pytest.approx(peak)
        assert table[start, joint] == 0.0
        assert table[start + 10, joint] == pytest.approx(peak * 0.5)  # half the 0.1 s ramp
        assert table[end, joint] == pytest.approx(peak * 0.5)  # half the 0.2 s fall
        assert table[end + 20, joint] == pytest.approx(0.0)  # 0.1 s after touchdown
        others = np.delete(table[start:end], joint, axis=1)
        assert np.all(others == 0.0)
    rest = table[: singles[0].start_tick]
    assert np.all(rest == 0.0)
