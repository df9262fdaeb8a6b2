"""The four controllers behind JointController: factory, call protocol, bumpless start, Kdist."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controller import (
    CONTROLLER_NAMES,
    ControllerKind,
    ControllerParams,
    ControllerUsageError,
    FlexibleJointParams,
    JointController,
    NoGravity,
    PendulumGravity,
    TrackingGain,
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


def test_each_kind_builds_the_block_its_name_says() -> None:
    """pid passes the reference, gc adds ug, gc+lqr integrates the error, only +dob has a DOB.
    Checked by behaviour, one tick each, on a link 0.1 rad below its reference."""
    gravity = PendulumGravity(mass_kg=2.0, com_distance_m=0.35)
    reference, motor, link = np.array([0.3]), np.array([0.2]), np.array([0.2])
    ug = 2.0 * 9.81 * 0.35 * math.cos(0.3) / 2000.0
    goals = {}
    for kind in ControllerKind:
        controller = make_controller(
            kind, ControllerParams.paper(1), sm=SM, dt_s=DT_S, gravity=gravity
        )
        assert controller.name == kind.value and kind.value in CONTROLLER_NAMES
        controller.reset(motor, link, reference, goal_in_force_rad=motor)
        goals[kind] = controller.step(motor, link, reference)[0]
        if kind is ControllerKind.GC_LQR_DOB:
            controller.set_kdist(0.5)  # has a DOB
        else:
            with pytest.raises(ControllerUsageError, match="no disturbance observer"):
                controller.set_kdist(0.5)
    assert goals[ControllerKind.PID] == pytest.approx(0.3, abs=1e-15)
    assert goals[ControllerKind.GC] == pytest.approx(0.3 + ug, abs=1e-15)
    # gc+lqr: from the goal in force, the first increment -Ke e = +0.1 Ke (the link is below)
    assert 0.2 < goals[ControllerKind.GC_LQR] < 0.2 + 0.1
    assert len(CONTROLLER_NAMES) == len(ControllerKind) == 4


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


@pytest.mark.parametrize("name", CONTROLLER_NAMES)
def test_start_is_bumpless_from_the_goal_in_force_under_gravity(name: str) -> None:
    """The servo holds the link at the reference under gravity, short of its goal by the lag
    tau_g / k_s (k_s = 785 N m/rad: 8.8 mrad here). The first goal is the goal in force, not the
    measured motor angle, for every controller at rest. For the DOB the lag is a disturbance
    it must see: q(1) = (theta_m - a theta_m) / b - u = theta_m - goal (at rest, any a, b), so
    its first goal moves by Kdist (1 - alpha) (theta_m - goal) and nothing else."""
    gravity = PendulumGravity(mass_kg=2.0, com_distance_m=0.35)
    theta_d = np.array([0.4])
    tau_g = 2.0 * 9.81 * 0.35 * math.cos(0.4)
    ug = tau_g / 2000.0
    lag = tau_g / 785.0
    goal_in_force = (theta_d if name == "pid" else theta_d + ug).copy()
    motor, link = goal_in_force - lag, theta_d.copy()
    if name != "pid":  # the gc holds the spring's deflection with the motor
        link = motor - ug
    kdist = 0.8
    params = ControllerParams.paper(1, kdist=kdist)
    controller = make_controller(name, params, sm=SM, dt_s=DT_S, gravity=gravity)
    controller.reset(motor, link, theta_d if name in ("pid", "gc") else link, goal_in_force)
    reference = theta_d if name in ("pid", "gc") else link  # LQR at rest: e = 0
    goal = controller.step(motor, link, reference)
    expected = goal_in_force.copy()
    if name == "gc+lqr+dob":
        alpha = 0.7  # the default Q filter: the lab's pole
        expected = goal_in_force + kdist * (1 - alpha) * (motor - goal_in_force)
    np.testing.assert_allclose(goal, expected, rtol=0, atol=1e-12)
    assert abs(goal[0] - motor[0]) > 0.5 * lag  # the old start (measured angle) was a bump


@pytest.mark.parametrize("name", ["gc+lqr", "gc+lqr+dob"])
def test_off_the_reference_the_first_goal_moves_by_the_first_lqr_increment_only(
    name: str,
) -> None:
    gravity = PendulumGravity(mass_kg=2.0, com_distance_m=0.35)
    params = ControllerParams.paper(1)
    controller = make_controller(name, params, sm=SM, dt_s=DT_S, gravity=gravity)
    theta_d = np.array([0.4])
    ug = gravity.gravity_torque(theta_d) / 2000.0
    motor, link = theta_d + ug, theta_d.copy()
    controller.reset(motor, link, theta_d - 0.1, goal_in_force_rad=motor)
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
def test_kdist_step_moves_the_goal_only_as_the_gain_change_implies(reading: str) -> None:
    """Without a ramp (kdist_ramp_s = 0): at rest under a constant disturbance d (q = d, dx = 0)
    the first goal after the switch moves by (Kdist' - Kdist) d in both readings: literal, the
    held term Kdist q steps; accumulated, the rest balance duc = -Kdist d is broken by that
    much per tick."""
    params = ControllerParams.paper(1, kdist=0.2, composition=reading, kdist_ramp_s=0.0)
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


def test_a_swapped_lqr_gain_acts_from_the_next_tick() -> None:
    """A hand-made gain (0.05 per tick on e, nothing on dx): one tick with e = -0.2 from rest
    moves the goal by exactly +0.01."""
    controller = _make("gc+lqr")
    zero = np.zeros(1)
    controller.reset(zero, zero, zero, goal_in_force_rad=zero)
    controller.step(zero, zero, zero)
    controller.notify_applied(zero)
    controller.set_lqr_gain(  # type: ignore[attr-defined]
        TrackingGain(np.array([[0.05]]), np.zeros((1, 3)), DT_S, float("nan"))
    )
    goal = controller.step(zero, zero, np.array([0.2]))
    assert goal[0] == pytest.approx(0.01, abs=1e-15)
    wrong_rate = design_discrete_tracking_lqr(FlexibleJointParams.uniform(1), SM, 0.001)
    with pytest.raises(ValueError, match="designed for dt"):
        controller.set_lqr_gain(wrong_rate)  # type: ignore[attr-defined]
