"""The identification's models checked against closed forms, an ODE solver and MuJoCo's step."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.integrate
import scipy.interpolate

from hil.identify import GearParams, JointLog, KnownJointFigures, MotorParams, ServoParams
from hil.identify.models import (
    JointState,
    advance,
    first_order_response,
    goal_integral,
    integral_from_log,
    link_response,
    propagate,
)

PERIOD_S = 0.005
N = 400


def make_log(motor_angle, motor_velocity, link_angle, goal=None, current=None) -> JointLog:
    n = len(motor_angle)
    return JointLog(
        np.arange(n) * PERIOD_S,
        np.zeros(n) if goal is None else goal,
        motor_angle,
        link_angle,
        motor_velocity,
        np.zeros(n) if current is None else current,
    )


def test_first_order_response_is_the_exact_step_response_of_4() -> None:
    goal = np.full(200, 0.3)
    kp = 10.0
    theta = first_order_response(goal, 0.1, kp, PERIOD_S)
    t = np.arange(200) * PERIOD_S
    np.testing.assert_allclose(theta, 0.3 + (0.1 - 0.3) * np.exp(-kp * t), atol=1e-12)


def test_propagate_matches_the_recursion() -> None:
    rng = np.random.default_rng(1)
    transition = np.array([[0.9, 0.05, 0.0], [-0.1, 0.8, 0.02], [0.0, 0.01, 0.99]])
    drive = rng.normal(size=(300, 3))
    initial = np.array([0.3, -0.2, 1.0])
    expected = np.empty((301, 3))
    expected[0] = initial
    for k in range(300):
        expected[k + 1] = transition @ expected[k] + drive[k]
    np.testing.assert_allclose(propagate(transition, drive, initial), expected, atol=1e-9)


def test_link_response_matches_an_ode_solver_on_the_hermite_motor_curve() -> None:
    """(1) + (3) with gravity; the motor curve between samples is the cubic Hermite curve and
    cos(theta_j) is linear between the samples' values, as the model states."""
    known = KnownJointFigures(link_inertia_kg_m2=0.36, gravity_moment_kg_m=0.6)
    gear = GearParams(1800.0, 70.0, 0.0)
    t = np.arange(N) * PERIOD_S
    start = 0.2  # motor at rest first, so the link starts at rest in equilibrium
    s = np.clip(t - start, 0, None)
    motor = 0.2 + 0.05 * np.sin(2 * np.pi * 2.0 * s) * (1 - np.exp(-3 * s))
    velocity = np.gradient(motor, PERIOD_S)
    velocity[t <= start] = 0.0
    # analytic derivative (the model must see consistent angles and velocities)
    velocity = 0.05 * (
        2 * np.pi * 2.0 * np.cos(2 * np.pi * 2.0 * s) * (1 - np.exp(-3 * s))
        + np.sin(2 * np.pi * 2.0 * s) * 3 * np.exp(-3 * s)
    )
    velocity[t <= start] = 0.0
    g = known.gravity_torque_nm
    link0 = 0.2 - g * math.cos(0.2) / gear.stiffness_nm_per_rad  # first guess
    for _ in range(20):  # equilibrium K (theta_m - theta_j) = g cos(theta_j)
        link0 = 0.2 - g * math.cos(link0) / gear.stiffness_nm_per_rad
    motor_curve = scipy.interpolate.CubicHermiteSpline(t, motor, velocity)
    motor_rate = motor_curve.derivative()

    # The model's gravity input is linear in the samples of cos(theta_j) it is given. Feed the
    # reference ODE the same samples (the model's own output: if the model is right, the
    # reference reproduces them), so one solve checks the discretisation.
    log = make_log(motor, velocity, np.full(N, link0))
    for _ in range(2):  # the model's output with its output as the measured link angle
        link_samples = link_response(log, gear, known).angle_rad
        log = make_log(motor, velocity, link_samples)
    cos_samples = np.cos(link_samples)

    def rhs(time, x):
        tau = gear.stiffness_nm_per_rad * (motor_curve(time) - x[0]) + (
            gear.damping_nms_per_rad * (motor_rate(time) - x[1])
        )
        return [x[1], (tau - g * np.interp(time, t, cos_samples)) / 0.36]

    sol = scipy.integrate.solve_ivp(
        rhs, (0, t[-1]), [link0, 0.0], t_eval=t, rtol=1e-9, atol=1e-12, method="DOP853"
    )
    model = link_response(log, gear, known)
    np.testing.assert_allclose(model.angle_rad, sol.y[0], atol=1e-9)
    np.testing.assert_allclose(model.velocity_rad_s, sol.y[1], atol=1e-7)


def test_goal_integral_is_exact_for_a_cubic_motor_and_held_goals() -> None:
    t = np.arange(N) * PERIOD_S
    motor = 0.1 + 0.3 * t - 0.2 * t**2 + 0.05 * t**3
    velocity = 0.3 - 0.4 * t + 0.15 * t**2
    goal = np.where(t < 1.0, 0.5, -0.1)
    expected_goal = np.concatenate([[0.0], np.cumsum(goal[:-1] * PERIOD_S)])
    expected_motor = 0.1 * t + 0.15 * t**2 - 0.2 / 3 * t**3 + 0.0125 * t**4
    log = make_log(motor, velocity, motor, goal=goal)
    np.testing.assert_allclose(goal_integral(log), expected_goal - expected_motor, atol=1e-12)


def test_integral_reconstruction_with_the_goal_on_the_motor() -> None:
    """e = 0: the velocity-loop integral only sees -theta_m': iota = iota0 - kv/Ti (dtheta)."""
    t = np.arange(N) * PERIOD_S
    motor = 0.2 * np.sin(t)
    log = make_log(motor, 0.2 * np.cos(t), motor, goal=motor)
    servo = ServoParams(10.0, 80.0, 4.0, integral_initial_nm=1.5)
    iota = integral_from_log(log, servo)
    # E_k is not zero (the goal is held, the motor moves within each period), but small
    assert np.allclose(iota, 1.5 - 20.0 * (motor - motor[0]), atol=20 * 10 * 0.2 * PERIOD_S)


KNOWN = KnownJointFigures(link_inertia_kg_m2=0.363, gravity_moment_kg_m=0.614)
GEAR = GearParams(2000.0, 100.0, 0.0)
SERVO = ServoParams(10.0, 78.5, 15.0)
MOTOR = MotorParams(0.25, 1.14, 3.95)


def test_advance_holds_a_static_equilibrium_against_gravity() -> None:
    link = 0.3
    gear_torque = KNOWN.gravity_torque_nm * math.cos(link)
    motor = link + gear_torque / GEAR.stiffness_nm_per_rad
    state = JointState(*(np.array([v]) for v in (motor, 0.0, link, 0.0, gear_torque)))
    after, current = advance(state, np.array([motor]), GEAR, SERVO, MOTOR, KNOWN, 0.005, 0.001)
    assert after.motor_angle_rad[0] == pytest.approx(motor, abs=1e-12)
    assert after.link_angle_rad[0] == pytest.approx(link, abs=1e-12)
    assert after.integral_nm[0] == pytest.approx(gear_torque, abs=1e-12)
    assert current[0] == pytest.approx(gear_torque / KNOWN.torque_constant_nm_per_a, abs=1e-12)


def test_coulomb_friction_holds_the_motor_until_the_servo_exceeds_it() -> None:
    weightless = KnownJointFigures(link_inertia_kg_m2=0.363, gravity_moment_kg_m=0.0)
    rest = JointState(*(np.zeros(2) for _ in range(5)))
    stiffness = SERVO.position_gain_per_s * SERVO.velocity_gain_nms_per_rad  # N m per rad
    goals = np.array([0.5, 1.5]) * MOTOR.coulomb_friction_nm / stiffness  # below, above F_c
    after, _ = advance(rest, goals, GEAR, SERVO, MOTOR, weightless, 0.001, 0.001)
    assert after.motor_velocity_rad_s[0] == 0.0
    assert after.motor_velocity_rad_s[1] > 0.0


def test_one_physics_step_is_mujocos_implicitfast_step() -> None:
    """One 1 ms step of `advance` against TestbedPlant (the emulator's MuJoCo model) from the
    same state, friction-free (MuJoCo's friction is a soft constraint, not modelled exactly)."""
    mujoco = pytest.importorskip("mujoco")
    from sim_backend.plant import TestbedPlant, TestbedPlantParams

    params = TestbedPlantParams(gearbox_coulomb_friction_nm=0.0)
    kv = 78.5
    plant = TestbedPlant(params, kv)
    model, data = plant.model, plant.data
    q1, v1, q2, v2 = 0.01, 0.3, 0.008, -0.2
    data.qpos[:] = [q1, q2 - q1]  # MuJoCo's second coordinate is the deflection
    data.qvel[:] = [v1, v2 - v1]
    mujoco.mj_forward(model, data)
    mass = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, mass)
    # qfrc_bias of the link's dof is the gravity torque g m r cos(theta_j) (planar: no Coriolis)
    gravity_moment = float(data.qfrc_bias[1]) / (params.gravity_m_s2 * math.cos(q2))
    known = KnownJointFigures(float(mass[1, 1]), gravity_moment)
    motor = MotorParams(
        float(mass[0, 0] - mass[1, 1]), params.gearbox_viscous_friction_nms_per_rad, 0
    )
    gear = GearParams(params.gear_stiffness_nm_per_rad, params.gear_damping_nms_per_rad)
    servo = ServoParams(10.0, kv, 1e12)  # no integral action over one step
    goal = 0.06
    plant.set_servo(servo.position_gain_per_s * (goal - q1), 1000.0)
    mujoco.mj_step(model, data)
    state = JointState(*(np.array([v]) for v in (q1, v1, q2, v2, 0.0)))
    after, current = advance(state, np.array([goal]), gear, servo, motor, known, 0.001, 0.001)
    assert after.motor_velocity_rad_s[0] == pytest.approx(data.qvel[0], abs=1e-9)
    assert after.link_velocity_rad_s[0] == pytest.approx(data.qvel[0] + data.qvel[1], abs=1e-9)
    assert after.motor_angle_rad[0] == pytest.approx(data.qpos[0], abs=1e-12)
    assert after.link_angle_rad[0] == pytest.approx(data.qpos[0] + data.qpos[1], abs=1e-12)
    assert current[0] * known.torque_constant_nm_per_a == pytest.approx(data.actuator_force[0])
