"""Gravity compensator (5)-(8): the statics of (1)-(3) for the pendulum testbed, the force split."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from controller import (
    ControllerParams,
    NoGravity,
    PendulumGravity,
    make_controller,
    single_link_sm,
    support_force_split,
)

K = 2000.0


def _static_link_angle(motor_angle: float, mass: float, distance: float) -> float:
    """Solve the rest state of (1) with (3): K (theta_m - theta_j) = m g r cos(theta_j)."""
    holding = mass * 9.81 * distance

    def residual(link: float) -> float:
        return K * (motor_angle - link) - holding * math.cos(link)

    # the spring torque falls by K per rad, gravity's by at most m g r < K: one root nearby
    return brentq(residual, motor_angle - 1.0, motor_angle + 1.0, xtol=1e-15)


@pytest.mark.parametrize("theta_d", [-1.2, -0.4, 0.0, 0.3, 1.0, math.pi / 2])
@pytest.mark.parametrize("mass, distance", [(2.0, 0.35), (5.0, 0.5)])
def test_gc_goal_puts_the_link_exactly_on_the_reference(
    theta_d: float, mass: float, distance: float
) -> None:
    gravity = PendulumGravity(mass_kg=mass, com_distance_m=distance)
    params = ControllerParams.paper(1)
    sm = single_link_sm(0.25)
    gc = make_controller("gc", params, sm=sm, dt_s=0.005, gravity=gravity)
    pid = make_controller("pid", params, sm=sm, dt_s=0.005, gravity=gravity)
    reference = np.array([theta_d])
    for controller in (gc, pid):
        controller.reset(reference, reference, reference)
    gc_goal = gc.step(reference, reference, reference)[0]
    pid_goal = pid.step(reference, reference, reference)[0]
    assert gc_goal == pytest.approx(theta_d + mass * 9.81 * distance * math.cos(theta_d) / K)
    assert _static_link_angle(gc_goal, mass, distance) == pytest.approx(theta_d, abs=1e-12)
    sag = _static_link_angle(pid_goal, mass, distance) - theta_d
    # without GC the link sags; linearised: -tau_g / (K + dtau_g/dtheta)
    holding = mass * 9.81 * distance
    expected_sag = -holding * math.cos(theta_d) / (K - holding * math.sin(theta_d))
    assert sag == pytest.approx(expected_sag, abs=1e-6)


def test_pendulum_torque_sign_convention() -> None:
    gravity = PendulumGravity(mass_kg=[2.0, 1.0], com_distance_m=[0.35, 0.2], gravity_m_s2=9.81)
    torque = gravity.gravity_torque(np.array([0.0, math.pi / 2]))
    assert torque[0] == pytest.approx(2.0 * 9.81 * 0.35)  # horizontal: full holding torque
    assert torque[1] == pytest.approx(0.0, abs=1e-12)  # straight up: none
    assert gravity.gravity_torque(np.array([math.pi, 0.0]))[0] == pytest.approx(-2.0 * 9.81 * 0.35)
    np.testing.assert_array_equal(NoGravity().gravity_torque(np.array([0.3, 0.1])), [0.0, 0.0])
    with pytest.raises(ValueError, match="equal-length"):
        PendulumGravity(mass_kg=[1.0, 2.0], com_distance_m=0.3)
    with pytest.raises(ValueError, match="mass_kg"):
        PendulumGravity(mass_kg=-1.0, com_distance_m=0.3)


def test_support_force_split_follows_6_and_7() -> None:
    left, right = np.array([0.0, 0.1, 0.0]), np.array([0.0, -0.1, 0.0])
    weight = np.array([0.0, 0.0, 48.0 * 9.81])
    f_right, f_left = support_force_split(left, left, right, weight)
    np.testing.assert_allclose(f_right, 0.0)  # CoM over the left foot: left single support
    np.testing.assert_allclose(f_left, weight)
    f_right, f_left = support_force_split(np.array([0.05, 0.05, 0.8]), left, right, weight)
    np.testing.assert_allclose(f_right, 0.25 * weight)  # a quarter of the way to the right foot
    np.testing.assert_allclose(f_right + f_left, weight)
    f_right, _ = support_force_split(np.array([0.0, -0.3, 0.8]), left, right, weight)
    np.testing.assert_allclose(f_right, weight)  # beyond the right foot: clipped to 1
    with pytest.raises(ValueError, match="same position"):
        support_force_split(left, left, left, weight)
