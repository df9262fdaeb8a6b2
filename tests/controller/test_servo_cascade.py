"""The servo cascade as the LQR's model (controller/servo_cascade.py), checked against analysis:
its limit is the paper's (4), its static stiffness is Kpp kv, one joint's design is the textbook
DARE written out by hand, and that design's sampled loop (written from the equations, the
motor velocity by the encoder's difference) has the designed spectral radius."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg

from controller import FlexibleJointParams, LqrWeights, ServoCascadeParams
from controller.lqr_designs import design_discrete_tracking_lqr
from controller.model import single_link_sm
from controller.servo_cascade import cascade_state_space

DT_S = 0.005
K, D, KPP = 2000.0, 100.0, 10.0
KV, J, B = 78.5, 0.25, 1.14
INERTIA = 0.376  # the testbed's link


def test_the_goal_to_motor_transfer_tends_to_the_papers_servo() -> None:
    """A link of no inertia carries nothing: J w' = kv (Kpp (u - th) - w) - b w, and with J, b
    -> 0 the motor follows its goal as (4) says, theta_m / u = Kpp / (s + Kpp); with the rotor's
    J and b it is Kpp kv / (J s^2 + (kv + b) s + Kpp kv). Compared at s = j w."""
    joints = FlexibleJointParams.uniform(1, K, D, KPP)
    light_link = single_link_sm(1e-6)
    for inertia, friction in ((1e-9, 0.0), (J, B)):
        servo = ServoCascadeParams(np.array([KV]), np.array([inertia]), np.array([friction]))
        model = cascade_state_space(joints, servo, light_link)
        for w in (1.0, 10.0, 50.0):
            s = 1j * w
            x = np.linalg.solve(s * np.eye(4) - model.a, model.b)  # states per unit goal
            expected = KPP * KV / (inertia * s**2 + (KV + friction) * s + KPP * KV)
            assert x[0, 0] == pytest.approx(expected, rel=1e-4)
            if inertia < 1e-6:
                assert x[0, 0] == pytest.approx(KPP / (s + KPP), rel=1e-4)


def test_the_static_stiffness_against_a_held_link_is_kpp_kv_in_series_with_k() -> None:
    joints = FlexibleJointParams.uniform(1, K, D, KPP)
    servo = ServoCascadeParams.h54(1)
    assert servo.static_stiffness_nm_per_rad(joints)[0] == pytest.approx(KPP * KV)
    model = cascade_state_space(joints, servo, single_link_sm(INERTIA))
    # hold the link at 0, goal 0: a torque tau on the link side needs a motor lag tau / (Kpp kv)
    # and a deflection tau / K; from the motor row at rest: kv Kpp (u - th) = tau_j.
    a = model.a
    # at rest with theta_j = 0: 0 = -(Kpp kv + K)/J theta_m + (Kpp kv)/J u  =>  theta_m/u
    ratio = -(a[1, 0] ** -1) * model.b[1, 0]
    assert ratio == pytest.approx(KPP * KV / (KPP * KV + K), rel=1e-12)  # 0.28: k_s/(k_s + K)


def _textbook_gain(method: str) -> tuple[np.ndarray, float]:
    """One joint, written out from the equations: x = [th_m, w_m, th_j, w_j], the augmented
    [e; dx] with the sampled model, Q = diag(10, 1, 1, 1, 1), R = 1, scipy's DARE."""
    a = np.array(
        [
            [0, 1, 0, 0],
            [-(KPP * KV + K) / J, -(KV + B + D) / J, K / J, D / J],
            [0, 0, 0, 1],
            [K / INERTIA, D / INERTIA, -K / INERTIA, -D / INERTIA],
        ]
    )
    b = np.array([[0], [KPP * KV / J], [0], [0]])
    c = np.array([[0, 0, 1, 0]])
    big = np.zeros((5, 5))
    big[:4, :4], big[:4, 4:] = a, b
    e = scipy.linalg.expm(big * DT_S)
    ad, bd = e[:4, :4], e[:4, 4:]
    a_aug = np.block([[np.eye(1), c @ ad], [np.zeros((4, 1)), ad]])
    b_aug = np.vstack([c @ bd, bd])
    q = np.diag([10.0, 1, 1, 1, 1])
    p = scipy.linalg.solve_discrete_are(a_aug, b_aug, q, np.eye(1))
    gain = np.linalg.solve(np.eye(1) + b_aug.T @ p @ b_aug, b_aug.T @ p @ a_aug)
    return gain, float(np.max(np.abs(np.linalg.eigvals(a_aug - b_aug @ gain))))


def test_one_joints_cascade_design_is_the_textbook_design() -> None:
    joints = FlexibleJointParams.uniform(1, K, D, KPP)
    servo = ServoCascadeParams(np.array([KV]), np.array([J]), np.array([B]))
    for coupling in ("full", "diagonal", "closed-chain"):
        gain = design_discrete_tracking_lqr(
            joints, single_link_sm(INERTIA), DT_S, LqrWeights(), "zoh", coupling, servo
        )
        textbook, radius = _textbook_gain("zoh")
        assert gain.error_gain[0, 0] == pytest.approx(textbook[0, 0], rel=1e-8)
        assert gain.state_increment_gain[0, 0] == pytest.approx(textbook[0, 1], rel=1e-8)
        assert gain.motor_velocity_increment_gain[0, 0] == pytest.approx(textbook[0, 2], rel=1e-8)
        assert gain.state_increment_gain[0, 1] == pytest.approx(textbook[0, 3], rel=1e-8)
        assert gain.state_increment_gain[0, 2] == pytest.approx(textbook[0, 4], rel=1e-8)
        assert gain.spectral_radius == pytest.approx(radius, rel=1e-10)


def test_the_sampled_loop_of_one_joint_has_the_designed_radius() -> None:
    """The plant (the cascade, sampled exactly), the controller as it runs: increments of the
    samples, the velocities by differences. With exact velocities the loop is the designed one
    (spectral radius equal); with the differences it stays within 1 % of it."""
    joints = FlexibleJointParams.uniform(1, K, D, KPP)
    servo = ServoCascadeParams(np.array([KV]), np.array([J]), np.array([B]))
    gain = design_discrete_tracking_lqr(joints, single_link_sm(INERTIA), DT_S, servo=servo)
    model = cascade_state_space(joints, servo, single_link_sm(INERTIA))
    big = np.zeros((5, 5))
    big[:4, :4], big[:4, 4:] = model.a, model.b
    e = scipy.linalg.expm(big * DT_S)
    phi, gamma = e[:4, :4], e[:4, 4:]
    ke = gain.error_gain[0, 0]
    km, kj, kl = gain.state_increment_gain[0]
    kw = gain.motor_velocity_increment_gain[0, 0]

    def loop(exact: bool) -> np.ndarray:
        # z = [x (4); previous samples th_m, w_m, th_j, w_j (4); u_prev]
        def step(z):
            x, prev, u_prev = z[:4], z[4:8], z[8]
            if exact:
                sample = x.copy()
            else:  # velocities by the encoders' backward differences
                sample = np.array([x[0], (x[0] - prev[0]) / DT_S, x[2], (x[2] - prev[2]) / DT_S])
            inc = sample - prev
            u = u_prev - (ke * sample[2] + km * inc[0] + kw * inc[1] + kj * inc[2] + kl * inc[3])
            return np.concatenate([phi @ x + gamma[:, 0] * u, sample, [u]])

        return np.array([step(col) for col in np.eye(9)]).T

    radius_exact = np.max(np.abs(np.linalg.eigvals(loop(exact=True))))
    assert radius_exact == pytest.approx(gain.spectral_radius, rel=1e-9)
    radius_measured = np.max(np.abs(np.linalg.eigvals(loop(exact=False))))
    assert radius_measured < 1 and abs(radius_measured - gain.spectral_radius) < 0.01
    assert math.isfinite(gain.dominant_time_constant_s)


def test_the_cascade_refuses_eulers_design() -> None:
    joints = FlexibleJointParams.uniform(1)
    with pytest.raises(ValueError, match="Euler"):
        design_discrete_tracking_lqr(
            joints, single_link_sm(INERTIA), DT_S, method="euler", servo=ServoCascadeParams.h54(1)
        )
