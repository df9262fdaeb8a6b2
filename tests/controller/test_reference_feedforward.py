"""The reference feed-forward of the LQR's increment (ControllerParams.reference_feedforward):
on the same samples, gc+lqr's goal with it and without it differ by exactly the reference's
change since the reset (duc gains d theta_d each tick; nothing else changes). (With the DOB the
goals differ by more: its estimate compares the motor with the goal sent, which differs.)"""

from __future__ import annotations

import numpy as np
import pytest

from controller import ControllerParams, NoGravity, PlannedMotion, make_controller

DT_S = 0.005


def _goals(feedforward: bool, kind: str) -> np.ndarray:
    params = ControllerParams.paper(
        2, discretisation="euler", reference_feedforward=feedforward, kdist=0.5
    )
    controller = make_controller(
        kind, params, sm=np.diag([1 / 0.376, 1 / 0.5]), dt_s=DT_S, gravity=NoGravity()
    )
    rng = np.random.default_rng(0)
    reference = np.array([0.1, -0.2])
    controller.reset(np.zeros(2), np.zeros(2), reference, np.zeros(2))
    goals = []
    for k in range(50):
        ramp = reference + 0.01 * k * np.array([1.0, -0.5])
        motor, link = rng.normal(scale=1e-3, size=(2, 2))
        goal = controller.step(motor, link, ramp)
        controller.notify_applied(goal)
        goals.append(goal - 0.01 * k * np.array([1.0, -0.5]) * feedforward)
    return np.array(goals)


def test_the_feedforward_adds_the_references_change_and_nothing_else() -> None:
    assert np.allclose(_goals(True, "gc+lqr"), _goals(False, "gc+lqr"), atol=1e-12)
    assert not np.allclose(_goals(True, "gc+lqr+dob"), _goals(False, "gc+lqr+dob"))


# --- a planned motion (controller/planned_motion.py) ------------------------------------------


def _along_the_plan(planned: bool, servo: bool = False, kind: str = "gc+lqr") -> np.ndarray:
    """gc+lqr with the reference feed-forward on a robot that follows a 0.4 rad/s ramp (and
    1 rad/s the other joint) exactly, motor and link: u - theta_d per tick."""
    params = ControllerParams.paper(
        2, discretisation="euler", reference_feedforward=True, servo_feedforward=servo
    )
    controller = make_controller(
        kind, params, sm=np.diag([1 / 0.376, 1 / 0.5]), dt_s=DT_S, gravity=NoGravity()
    )
    velocity = np.array([0.4, -1.0])
    start = np.array([0.1, -0.2])
    controller.reset(start, start, start, start)
    lead = []
    for k in range(1, 40):
        theta = start + velocity * DT_S * k
        increment = velocity * DT_S
        velocity_increment = velocity if k == 1 else np.zeros(2)  # 0 -> v at the first tick
        if planned:
            controller.set_planned_motion(PlannedMotion(increment, velocity_increment))
        goal = controller.step(theta, theta, theta)
        controller.notify_applied(goal)
        lead.append(goal - theta)
    return np.array(lead), controller


def test_about_the_plan_the_lqr_no_longer_brakes_a_followed_reference() -> None:
    """A robot on its plan: with the plan's increments the LQR sees no departure and the goal
    stays on the reference (u - theta_d = 0 every tick); without them its state-increment
    gains act on the motion itself and the goal falls behind by (K_m + K_j) d theta per tick
    (the motor and link increment gains' diagonal, 2 x 2 here), by hand."""
    lead, _ = _along_the_plan(True)
    assert np.abs(lead).max() < 1e-12
    braked, controller = _along_the_plan(False)
    gain = controller.lqr_gain.state_increment_gain
    per_tick = (gain[:, :2] + gain[:, 2:4]) @ (np.array([0.4, -1.0]) * DT_S)
    # from the second tick on (the first carries the link velocity's step, 0 -> v)
    assert np.allclose(np.diff(braked[1:], axis=0), -per_tick, rtol=1e-9, atol=1e-15)
    assert np.abs(per_tick).min() > 0.1 * np.abs(np.array([0.4, -1.0]) * DT_S).min()


def test_the_servo_feedforward_leads_by_the_velocity_over_kp() -> None:
    """servo_feedforward (ours): the inverse of (4), u = theta_d + d theta_d/dt / Kp. On the
    LQR it enters as increments of that lead, which sum to v / Kp once the ramp runs; on gc it
    is the lead itself, each tick, from the plan's increment."""
    lead, _ = _along_the_plan(True, servo=True)
    assert np.allclose(lead, np.array([0.4, -1.0]) / 10.0, rtol=0, atol=1e-12)
    params = ControllerParams.paper(2, servo_feedforward=True)
    gc = make_controller("gc", params, sm=np.eye(2), dt_s=DT_S, gravity=NoGravity())
    theta = np.array([0.1, -0.2])
    gc.reset(theta, theta, theta, theta)
    gc.set_planned_motion(PlannedMotion(np.array([0.002, -0.005]), np.zeros(2)))
    goal = gc.step(theta, theta, theta)
    assert goal == pytest.approx(theta + [0.04, -0.1], abs=1e-15)  # 0.4, -1 rad/s over Kp 10
    gc.notify_applied(goal)
    gc.set_planned_motion(None)
    assert gc.step(theta, theta, theta) == pytest.approx(theta, abs=1e-15)
