"""Composition (25), both readings: statics with the LQR's integral action, the gravity input
not mistaken for a disturbance, anti-windup. Derivations in controller/composition.py."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controller import (
    Composition,
    ControllerParams,
    DisturbanceObserver,
    FlexibleJointParams,
    NoGravity,
    PendulumGravity,
    make_controller,
    single_link_sm,
)
from controller.dob import LAB_DOB_CUTOFF_HZ
from controller.model import StateSpace, discretise, flexible_joint_state_space

DT_S = 0.005


class LoadedPlant:
    """(20) sampled (ZOH) with an input disturbance d [rad] and a load torque on the links [N m]:
    dtheta_m = Kp (u + d - theta_m),  ddtheta_j = Sm (tau_j - tau_load)."""

    def __init__(self, params: FlexibleJointParams, sm: np.ndarray) -> None:
        n = params.n_joints
        system = flexible_joint_state_space(params, sm)
        load = np.vstack([np.zeros((2 * n, n)), -sm])
        both = StateSpace(system.a, np.hstack([system.b, load]), system.c)
        sampled = discretise(both, DT_S, "zoh")
        self.n = n
        self.phi = sampled.a
        self.gamma_u = sampled.b[:, :n]
        self.gamma_load = sampled.b[:, n:]

    def step(
        self, x: np.ndarray, goal: np.ndarray, d: np.ndarray, load_nm: np.ndarray
    ) -> np.ndarray:
        return self.phi @ x + self.gamma_u @ (goal + d) + self.gamma_load @ load_nm


def _hold(
    reading: str,
    kdist: np.ndarray,
    sm: np.ndarray,
    d: np.ndarray,
    reference: np.ndarray,
    n_ticks: int = 3000,
) -> tuple[np.ndarray, object]:
    n = sm.shape[0]
    params = ControllerParams(
        joints=FlexibleJointParams.uniform(n),
        kdist=kdist,
        composition=reading,  # type: ignore[arg-type]
    )
    controller = make_controller("gc+lqr+dob", params, sm=sm, dt_s=DT_S, gravity=NoGravity())
    plant = LoadedPlant(params.joints, sm)
    x = np.zeros(3 * n)
    controller.reset(x[:n], x[n : 2 * n], reference)
    for _ in range(n_ticks):
        goal = controller.step(x[:n], x[n : 2 * n], reference)
        controller.notify_applied(goal)
        x = plant.step(x, goal, d, np.zeros(n))
    return x, controller


@pytest.mark.parametrize("kdist", [0.5, 1.0, 1.5])
@pytest.mark.parametrize("inertia", [0.25, 1.25])
def test_static_yield_under_each_reading(kdist: float, inertia: float) -> None:
    """literal: e -> 0 for every Kdist; accumulated: e -> Kdist d / Ke (grows linearly)."""
    sm = single_link_sm(inertia)
    d, reference = np.array([0.01]), np.array([0.2])
    x, controller = _hold("literal", np.array([kdist]), sm, d, reference)
    assert abs(x[1] - reference[0]) < 1e-9
    assert controller.terms.d_hat[0] == pytest.approx(kdist * d[0], abs=1e-9)  # type: ignore[attr-defined]
    x, controller = _hold("accumulated", np.array([kdist]), sm, d, reference)
    error_gain = controller.lqr_gain.error_gain[0, 0]  # type: ignore[attr-defined]
    assert x[1] - reference[0] == pytest.approx(kdist * d[0] / error_gain, rel=1e-6)
    assert x[0] == pytest.approx(x[1], abs=1e-12)  # at rest the spring is relaxed (no load)


def test_static_yield_of_coupled_joints_is_ke_inverse_kdist_d() -> None:
    sm = np.linalg.inv(np.array([[0.9, 0.25], [0.25, 0.15]]))
    kdist, d, reference = np.array([1.0, 0.4]), np.array([0.01, -0.02]), np.array([0.1, 0.3])
    x, controller = _hold("accumulated", kdist, sm, d, reference, n_ticks=4000)
    error_gain = controller.lqr_gain.error_gain  # type: ignore[attr-defined]
    expected = np.linalg.solve(error_gain, kdist * d)
    np.testing.assert_allclose(x[2:4] - reference, expected, rtol=1e-6, atol=1e-12)


@pytest.mark.parametrize("kdist", [0.5, 1.0])
def test_without_lqr_literal_gives_18_and_accumulated_ramps(kdist: float) -> None:
    a = math.exp(-10.0 * DT_S)
    b = 1 - a
    d, uc, ug = 0.01, 0.1, 0.05
    results = {}
    for reading in ("literal", "accumulated"):
        observer = DisturbanceObserver(np.array([10.0]), LAB_DOB_CUTOFF_HZ, DT_S, kdist)
        composition = Composition(1, reading)  # type: ignore[arg-type]
        theta_m = np.array([uc + ug])
        observer.reset(theta_m)
        composition.reset(theta_m, np.array([ug]))
        goals = []
        for _ in range(600):
            dob_term = observer.update(theta_m, composition.u)
            goal = composition.compose(np.zeros(1), dob_term, np.array([ug])).copy()
            composition.notify_applied(goal)
            goals.append(goal[0])
            theta_m = a * theta_m + b * (goal + d)
        results[reading] = (theta_m[0], np.diff(goals)[-1])
    assert results["literal"][0] == pytest.approx(uc + ug + (1 + kdist) * d, abs=1e-9)  # (18)
    assert results["accumulated"][1] == pytest.approx(kdist * d, rel=1e-9)  # u ramps


@pytest.mark.parametrize("reading", ["accumulated", "literal"])
def test_gravity_feed_forward_is_not_seen_as_a_disturbance(reading: str) -> None:
    """The DOB compares against the whole goal sent (ug included): with the nominal servo and
    the exact gravity feed-forward it estimates nothing, while the reference and ug move."""
    gravity = PendulumGravity(mass_kg=2.0, com_distance_m=0.35)
    params = ControllerParams(joints=FlexibleJointParams.uniform(1), composition=reading)  # type: ignore[arg-type]
    sm = single_link_sm(0.25)
    controller = make_controller("gc+lqr+dob", params, sm=sm, dt_s=DT_S, gravity=gravity)
    plant = LoadedPlant(params.joints, sm)
    theta_d0 = 0.3
    sag = gravity.gravity_torque(np.array([theta_d0])) / 2000.0
    x = np.array([theta_d0, theta_d0 - sag[0], 0.0])  # held by the servo, link sagging
    controller.reset(x[:1], x[1:2], np.array([theta_d0]))
    for k in range(1600):
        theta_d = np.array(
            [theta_d0 + (0.2 * math.sin(2 * math.pi * 0.5 * k * DT_S) if k < 800 else 0.0)]
        )
        goal = controller.step(x[:1], x[1:2], theta_d)
        controller.notify_applied(goal)
        assert abs(controller.terms.disturbance_estimate_rad[0]) < 1e-12
        x = plant.step(x, goal, np.zeros(1), gravity.gravity_torque(theta_d))
    terms = controller.terms
    assert terms.ug[0] == pytest.approx(gravity.gravity_torque(np.array([theta_d0]))[0] / 2000.0)
    assert x[1] == pytest.approx(theta_d0, abs=1e-9)  # link at the reference
    assert x[0] == pytest.approx(theta_d0 + terms.ug[0], abs=1e-9)  # motor leads by ug


@pytest.mark.parametrize("reading", ["accumulated", "literal"])
def test_clipped_goals_do_not_wind_up_or_look_like_disturbances(reading: str) -> None:
    params = ControllerParams(joints=FlexibleJointParams.uniform(1), composition=reading)  # type: ignore[arg-type]
    sm = single_link_sm(0.25)
    controller = make_controller("gc+lqr+dob", params, sm=sm, dt_s=DT_S, gravity=NoGravity())
    plant = LoadedPlant(params.joints, sm)
    x = np.zeros(3)
    reference = np.array([0.5])
    limit = 0.05
    controller.reset(x[:1], x[1:2], reference)
    error_gain = controller.lqr_gain.error_gain[0, 0]  # type: ignore[attr-defined]
    for k in range(800):
        goal = controller.step(x[:1], x[1:2], reference)
        if k < 600:  # the supervisor holds the goal at the limit for 3 s
            if k > 400:  # at rest against the limit: one tick's increment past it, no more
                assert goal[0] == pytest.approx(limit - error_gain * (limit - 0.5), rel=1e-6)
            goal = np.minimum(goal, limit)
        controller.notify_applied(goal)
        assert abs(controller.terms.disturbance_estimate_rad[0]) < 1e-12
        assert controller.terms.u[0] == goal[0]
        x = plant.step(x, goal, np.zeros(1), np.zeros(1))
    assert x[1] > 0.45  # released, it goes on to the reference
