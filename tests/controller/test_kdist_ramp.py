"""Kdist changes ramp inside the controller (the lab's cubic over 20 ticks), so that a walking
schedule cannot step the goal (literal reading) or its rate (accumulated readings).

Bounds from the cubic x(i) = x0 + dK (3 s^2 - 2 s^3), s = i / N: its largest step is
max_i [c(i/N) - c((i-1)/N)] <= 1.5 / N (the slope of c at s = 1/2), so at rest under a constant
input disturbance d (q = d) the DOB term Kdist q moves by at most 1.5 |dK d| / N per tick.
"""

from __future__ import annotations

import numpy as np
import pytest

from controller import (
    ControllerParams,
    CubicRamp,
    NoGravity,
    discretise,
    flexible_joint_state_space,
    make_controller,
    single_link_sm,
)

DT_S = 0.005
SM = single_link_sm(0.376)
D_RAD = 0.01  # constant input disturbance of the servo


def _switch_run(reading: str, ramp_s: float, n_after: int = 60) -> tuple[np.ndarray, object]:
    """At rest under d with Kdist 0.2, switch to 1.0; goals from two ticks before the switch."""
    params = ControllerParams.paper(
        1, kdist=0.2, composition=reading, kdist_ramp_s=ramp_s, discretisation="euler"
    )
    controller = make_controller("gc+lqr+dob", params, sm=SM, dt_s=DT_S, gravity=NoGravity())
    plant = discretise(flexible_joint_state_space(params.joints, SM), DT_S)
    x = np.zeros(3)
    reference = np.array([0.1])
    controller.reset(x[:1], x[1:2], reference, goal_in_force_rad=x[:1])
    goals = []
    switch_tick = 3000
    for k in range(switch_tick + n_after):
        if k == switch_tick:
            controller.set_kdist(1.0)
        goal = controller.step(x[:1], x[1:2], reference)
        controller.notify_applied(goal)
        if k >= switch_tick - 3:
            goals.append(goal[0])
        x = plant.a @ x + plant.b @ (goal + D_RAD)
    return np.array(goals), controller


def test_cubic_ramp_reaches_the_target_exactly_at_the_stated_tick() -> None:
    ramp = CubicRamp(np.array([0.2, 1.0]), ticks=20)
    ramp.set_target(np.array([1.0, 0.2]))
    values = [ramp.advance().copy() for _ in range(25)]
    np.testing.assert_array_equal(values[19], [1.0, 0.2])  # the 20th tick: exactly the target
    assert not np.array_equal(values[18], [1.0, 0.2])
    np.testing.assert_array_equal(values[24], [1.0, 0.2])
    steps = np.abs(np.diff(np.vstack([[0.2, 1.0], *values]), axis=0))
    assert np.max(steps) <= 1.5 * 0.8 / 20 + 1e-15
    # the lab's cubic: zero slope at both ends, half way at the middle
    assert values[9][0] == pytest.approx(0.2 + 0.8 * (3 * 0.25 - 2 * 0.125))
    assert steps[0, 0] == pytest.approx(0.8 * (3 / 400 - 2 / 8000))
    step = CubicRamp(np.array([0.2]), ticks=0)
    step.set_target(np.array([1.0]))
    np.testing.assert_array_equal(step.advance(), [1.0])


def test_a_new_target_during_a_ramp_starts_from_the_present_value() -> None:
    ramp = CubicRamp(np.array([0.0]), ticks=10)
    ramp.set_target(np.array([1.0]))
    for _ in range(5):
        ramp.advance()
    halfway = ramp.value.copy()
    assert halfway[0] == pytest.approx(0.5)
    ramp.set_target(np.array([0.0]))
    first = ramp.advance()[0]
    assert 0.45 < first < 0.5  # continuous: no jump back
    for _ in range(9):
        ramp.advance()
    assert ramp.value[0] == 0.0


def test_controller_kdist_reaches_the_target_at_the_ramps_last_tick() -> None:
    _, controller = _switch_run("accumulated", ramp_s=0.1, n_after=20)
    assert controller.kdist[0] == 1.0  # type: ignore[attr-defined]
    _, controller = _switch_run("accumulated", ramp_s=0.1, n_after=19)
    assert controller.kdist[0] < 1.0  # type: ignore[attr-defined]


def test_literal_reading_the_ramp_bounds_the_goal_increment() -> None:
    """literal: goal = uc + Kdist q + ug, so a step in Kdist steps the goal by dK d = 8 mrad in
    one tick; over 20 ticks no increment exceeds 1.5 dK d / 20 (+5 % for the LQR's reply)."""
    goals, _ = _switch_run("literal", ramp_s=0.0)
    jumps = np.abs(np.diff(goals))
    assert jumps[:2].max() < 1e-12  # at rest before
    assert jumps.max() == pytest.approx(0.8 * D_RAD, rel=0.02)
    goals, _ = _switch_run("literal", ramp_s=0.1)
    jumps = np.abs(np.diff(goals))
    assert jumps.max() <= 1.05 * 1.5 * 0.8 * D_RAD / 20


def test_accumulated_reading_the_ramp_bounds_the_change_of_the_goals_rate() -> None:
    """accumulated: u(k) = u(k-1) + duc + Kdist q, so a step in Kdist steps the goal's per-tick
    increment by dK d at once; the ramp spreads that change: <= 1.5 dK d / 20 per tick."""
    goals, _ = _switch_run("accumulated", ramp_s=0.0)
    change = np.abs(np.diff(goals, n=2))
    assert change.max() == pytest.approx(0.8 * D_RAD, rel=0.02)
    goals, _ = _switch_run("accumulated", ramp_s=0.1)
    change = np.abs(np.diff(goals, n=2))
    assert change.max() <= 1.05 * 1.5 * 0.8 * D_RAD / 20
