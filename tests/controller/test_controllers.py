"""The four controllers behind JointController: factory, call protocol, bumpless start, Kdist."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controller import (
    CONTROLLER_NAMES,
    ControllerParams,
    ControllerUsageError,
    FlexibleJointParams,
    JointController,
    LqrWeights,
    NoGravity,
    PendulumGravity,
    design_discrete_tracking_lqr,
    discretise,
    flexible_joint_state_space,
    make_controller,
    single_link_sm,
)

DT_S = 0.005
SM = single_link_sm(0.25)


def _make(name: str, **overrides: object) -> JointController:
    return make_controller(
        name, ControllerParams.paper(1, **overrides), sm=SM, dt_s=DT_S, gravity=NoGravity()
    )


def test_names_are_the_papers() -> None:
    assert CONTROLLER_NAMES == ("pid", "gc", "gc+lqr", "gc+lqr+dob")
    for name in CONTROLLER_NAMES:
        assert _make(name).name == name


def test_pid_passes_the_reference_and_gc_adds_the_gravity_input() -> None:
    gravity = PendulumGravity(mass_kg=[2.0, 1.0], com_distance_m=[0.35, 0.3])
    params = ControllerParams.paper(2)
    sm = np.diag([4.0, 6.0])
    reference = np.array([0.2, -0.5])
    measured = np.array([0.1, 0.1])
    pid = make_controller("pid", params, sm=sm, dt_s=DT_S, gravity=gravity)
    gc = make_controller("gc", params, sm=sm, dt_s=DT_S, gravity=gravity)
    for controller in (pid, gc):
        controller.reset(measured, measured, reference)
    np.testing.assert_array_equal(pid.step(measured, measured, reference), reference)
    expected_ug = np.array([2.0 * 9.81 * 0.35, 1.0 * 9.81 * 0.3]) * np.cos(reference) / 2000.0
    np.testing.assert_allclose(gc.step(measured, measured, reference), reference + expected_ug)
    terms = gc.terms
    np.testing.assert_allclose(terms.ug, expected_ug)
    np.testing.assert_allclose(terms.uc + terms.d_hat + terms.ug, terms.u)


@pytest.mark.parametrize("name", CONTROLLER_NAMES)
def test_call_protocol_is_enforced(name: str) -> None:
    controller = _make(name)
    zero = np.zeros(1)
    with pytest.raises(ControllerUsageError, match="before reset"):
        controller.step(zero, zero, zero)
    controller.reset(zero, zero, zero)
    with pytest.raises(ControllerUsageError, match="without a preceding step"):
        controller.notify_applied(zero)
    controller.step(zero, zero, zero)
    with pytest.raises(ControllerUsageError, match="without notify_applied"):
        controller.step(zero, zero, zero)
    controller.notify_applied(zero)
    with pytest.raises(ValueError, match=r"not finite for joints \[0\]"):
        controller.step(np.array([math.nan]), zero, zero)
    with pytest.raises(ValueError, match=r"shape \(1,\)"):
        controller.step(np.zeros(2), zero, zero)


@pytest.mark.parametrize("name", ["pid", "gc", "gc+lqr"])
def test_set_kdist_needs_a_dob(name: str) -> None:
    with pytest.raises(ControllerUsageError, match="no disturbance observer"):
        _make(name).set_kdist(0.5)


def test_factory_rejects_bad_configuration() -> None:
    params = ControllerParams.paper(1)
    with pytest.raises(ValueError, match="unknown controller 'lqr'"):
        make_controller("lqr", params, sm=SM, dt_s=DT_S, gravity=NoGravity())
    with pytest.raises(ValueError, match="1 x 1"):
        make_controller("gc+lqr", params, sm=np.eye(2), dt_s=DT_S, gravity=NoGravity())
    with pytest.raises(ValueError, match="dt_s"):
        make_controller("gc+lqr", params, sm=SM, dt_s=0.0, gravity=NoGravity())
    with pytest.raises(TypeError, match="GravityModel"):
        make_controller("gc", params, sm=SM, dt_s=DT_S, gravity=object())  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="gravity model returns shape"):
        make_controller(
            "gc", params, sm=SM, dt_s=DT_S, gravity=PendulumGravity([1.0, 1.0], [0.1, 0.1])
        )
    with pytest.raises(ValueError, match="composition"):
        ControllerParams.paper(1, composition="summed")
    with pytest.raises(ValueError, match="kdist needs 1 entries"):
        ControllerParams.paper(1, kdist=[1.0, 0.5])
    with pytest.raises(ValueError, match="discretisation"):
        ControllerParams.paper(1, discretisation="bilinear")
    with pytest.raises(ValueError, match="dob_cutoff_hz"):
        ControllerParams.paper(1, dob_cutoff_hz=-1.0)


@pytest.mark.parametrize("name", ["gc+lqr", "gc+lqr+dob"])
def test_reset_is_bumpless(name: str) -> None:
    """At rest on the reference the first goal is the present motor angle; off the reference
    it moves by the first LQR increment only, -Ke e."""
    gravity = PendulumGravity(mass_kg=2.0, com_distance_m=0.35)
    params = ControllerParams.paper(1)
    controller = make_controller(name, params, sm=SM, dt_s=DT_S, gravity=gravity)
    theta_d = np.array([0.4])
    ug = gravity.gravity_torque(theta_d) / 2000.0
    motor, link = theta_d + ug, theta_d.copy()
    controller.reset(motor, link, theta_d)
    np.testing.assert_allclose(controller.step(motor, link, theta_d), motor, atol=1e-15)
    controller.notify_applied(motor)
    controller.reset(motor, link, theta_d - 0.1)
    goal = controller.step(motor, link, theta_d - 0.1)
    error_gain = controller.lqr_gain.error_gain[0, 0]  # type: ignore[attr-defined]
    np.testing.assert_allclose(goal, motor - error_gain * 0.1, atol=1e-15)


def test_dob_with_zero_kdist_is_gc_plus_lqr() -> None:
    rng = np.random.default_rng(8)
    plant = discretise(flexible_joint_state_space(FlexibleJointParams.uniform(1), SM), DT_S)
    controllers = [_make("gc+lqr"), _make("gc+lqr+dob", kdist=0.0)]
    states = [np.array([0.0, 0.0, 0.0]) for _ in controllers]
    for controller, x in zip(controllers, states, strict=True):
        controller.reset(x[:1], x[1:2], np.zeros(1))
    for _ in range(200):
        reference = rng.normal(scale=0.1, size=1)
        goals = []
        for index, controller in enumerate(controllers):
            x = states[index]
            goal = controller.step(x[:1], x[1:2], reference)
            controller.notify_applied(goal)
            states[index] = plant.a @ x + plant.b @ (goal + 0.01)  # with a disturbance
            goals.append(goal)
        np.testing.assert_allclose(goals[0], goals[1], atol=1e-14)


@pytest.mark.parametrize("reading", ["accumulated", "literal"])
def test_kdist_schedule_moves_the_goal_only_as_the_gain_change_implies(reading: str) -> None:
    """At rest under a constant disturbance d (q = d, dx = 0) the first goal after the switch
    moves by (Kdist' - Kdist) d in both readings: literal, the held term Kdist q steps;
    accumulated, the rest balance duc = -Kdist d is broken by that much per tick."""
    params = ControllerParams.paper(1, kdist=0.2, composition=reading)
    controller = make_controller("gc+lqr+dob", params, sm=SM, dt_s=DT_S, gravity=NoGravity())
    plant = discretise(flexible_joint_state_space(params.joints, SM), DT_S)
    d = 0.01
    x = np.zeros(3)
    reference = np.array([0.1])
    controller.reset(x[:1], x[1:2], reference)
    goals = []
    for k in range(3001):
        if k == 3000:
            controller.set_kdist(1.0)
        goal = controller.step(x[:1], x[1:2], reference)
        controller.notify_applied(goal)
        goals.append(goal[0])
        x = plant.a @ x + plant.b @ (goal + d)
    assert goals[-2] - goals[-3] == pytest.approx(0.0, abs=1e-12)  # at rest before
    assert goals[-1] - goals[-2] == pytest.approx((1.0 - 0.2) * d, rel=1e-6)


def test_lqr_gain_can_be_swapped_between_ticks() -> None:
    controller = _make("gc+lqr")
    new_gain = design_discrete_tracking_lqr(
        FlexibleJointParams.uniform(1), single_link_sm(1.25), DT_S, LqrWeights()
    )
    controller.set_lqr_gain(new_gain)  # type: ignore[attr-defined]
    assert controller.lqr_gain is new_gain  # type: ignore[attr-defined]
    wrong_rate = design_discrete_tracking_lqr(FlexibleJointParams.uniform(1), SM, 0.001)
    with pytest.raises(ValueError, match="designed for dt"):
        controller.set_lqr_gain(wrong_rate)  # type: ignore[attr-defined]
