"""The flexible-joint model (1), (4), (19) -> (20) and its sampling, checked against analysis."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from controller.model import (
    FlexibleJointParams,
    discretise,
    flexible_joint_state_space,
    joint_torque_nm,
    single_link_sm,
    validate_sm,
)

DT_S = 0.005


def _three_joints() -> tuple[FlexibleJointParams, np.ndarray]:
    params = FlexibleJointParams(
        stiffness_nm_per_rad=np.array([2000.0, 1500.0, 2500.0]),
        damping_nms_per_rad=np.array([100.0, 80.0, 120.0]),
        servo_gain_per_s=np.array([10.0, 18.0, 12.0]),
    )
    inertia = np.array([[1.2, 0.3, 0.1], [0.3, 0.8, 0.2], [0.1, 0.2, 0.4]])
    return params, np.linalg.inv(inertia)


def test_state_space_is_equations_1_4_19_combined() -> None:
    params, sm = _three_joints()
    system = flexible_joint_state_space(params, sm)
    rng = np.random.default_rng(1)
    for _ in range(5):
        x = rng.normal(size=9)
        u = rng.normal(size=3)
        theta_m, theta_j, dtheta_j = x[:3], x[3:6], x[6:]
        dtheta_m = params.servo_gain_per_s * (u - theta_m)  # (4)
        tau_j = joint_torque_nm(params, theta_m, theta_j, dtheta_m, dtheta_j)  # (1)
        expected = np.concatenate([dtheta_m, dtheta_j, sm @ tau_j])  # (19)
        np.testing.assert_allclose(system.a @ x + system.b @ u, expected, rtol=1e-12, atol=1e-9)
    np.testing.assert_array_equal(system.c @ np.arange(9.0), [3.0, 4.0, 5.0])  # y = theta_j


def test_one_joint_poles_and_static_gain() -> None:
    """Poles: -Kp and the roots of s^2 + Sm D s + Sm K; static gain from u to theta_j is 1."""
    params = FlexibleJointParams.uniform(1)
    sm = single_link_sm(0.25)
    system = flexible_joint_state_space(params, sm)
    expected = np.sort(np.concatenate([[-10.0], np.roots([1.0, 4.0 * 100.0, 4.0 * 2000.0])]))
    np.testing.assert_allclose(np.sort(np.linalg.eigvals(system.a).real), expected, rtol=1e-10)
    static_gain = system.c @ np.linalg.solve(-system.a, system.b)
    np.testing.assert_allclose(static_gain, [[1.0]], rtol=1e-12)


def test_zoh_sampling_matches_integrating_the_ode_over_one_tick() -> None:
    params, sm = _three_joints()
    system = flexible_joint_state_space(params, sm)
    sampled = discretise(system, DT_S, "zoh")
    rng = np.random.default_rng(2)
    x0, u = rng.normal(size=9), rng.normal(size=3)
    solution = solve_ivp(
        lambda _t, x: system.a @ x + system.b @ u, (0, DT_S), x0, rtol=1e-12, atol=1e-12
    )
    np.testing.assert_allclose(sampled.a @ x0 + sampled.b @ u, solution.y[:, -1], atol=1e-8)
    # the servo row alone: exp(-Kp dt) and 1 - exp(-Kp dt)
    np.testing.assert_allclose(np.diag(sampled.a)[:3], np.exp(-params.servo_gain_per_s * DT_S))


def test_euler_sampling_is_the_labs_and_breaks_below_the_derived_inertia() -> None:
    params = FlexibleJointParams.uniform(1)
    system = flexible_joint_state_space(params, single_link_sm(0.5))
    euler = discretise(system, DT_S, "euler")
    np.testing.assert_allclose(euler.a, np.eye(3) + system.a * DT_S)
    np.testing.assert_allclose(euler.b, system.b * DT_S)
    threshold = 100.0 * DT_S / 2 - 2000.0 * DT_S**2 / 4  # D dt / 2 - K dt^2 / 4

    def euler_radius(inertia: float) -> float:
        model = discretise(
            flexible_joint_state_space(params, single_link_sm(inertia)), DT_S, "euler"
        )
        return float(np.max(np.abs(np.linalg.eigvals(model.a))))

    assert threshold == pytest.approx(0.2375)
    assert euler_radius(threshold * 1.01) < 1.0 < euler_radius(threshold * 0.99)


def test_params_broadcast_and_validate() -> None:
    params = FlexibleJointParams(
        stiffness_nm_per_rad=[2000.0, 2000.0], damping_nms_per_rad=100.0, servo_gain_per_s=10.0
    )
    assert params.n_joints == 2
    np.testing.assert_array_equal(params.servo_gain_per_s, [10.0, 10.0])
    with pytest.raises(ValueError, match="read-only"):
        params.stiffness_nm_per_rad[0] = 1.0
    with pytest.raises(ValueError, match="stiffness_nm_per_rad must be > 0"):
        FlexibleJointParams.uniform(1, stiffness_nm_per_rad=0.0)
    with pytest.raises(ValueError, match="needs 2 entries"):
        FlexibleJointParams([1.0, 2.0], [1.0, 2.0, 3.0], 10.0)
    with pytest.raises(ValueError, match="servo_gain_per_s must be > 0"):
        FlexibleJointParams.uniform(1, servo_gain_per_s=-1.0)


def test_sm_validation_says_what_is_wrong() -> None:
    with pytest.raises(ValueError, match="2 x 2"):
        validate_sm(np.eye(3), 2)
    with pytest.raises(ValueError, match="symmetric"):
        validate_sm(np.array([[1.0, 0.5], [0.0, 1.0]]), 2)
    with pytest.raises(ValueError, match="positive diagonal"):
        validate_sm(np.array([[1.0, 0.0], [0.0, 0.0]]), 2)
    with pytest.raises(ValueError, match="finite"):
        single_link_sm(math.inf)
    with pytest.raises(ValueError, match="dt_s"):
        discretise(flexible_joint_state_space(FlexibleJointParams.uniform(1), np.eye(1)), 0.0)
    with pytest.raises(ValueError, match="discretisation"):
        discretise(
            flexible_joint_state_space(FlexibleJointParams.uniform(1), np.eye(1)), 0.1, "rk4"
        )  # type: ignore[arg-type]
