"""The reference feed-forward of the LQR's increment (ControllerParams.reference_feedforward):
on the same samples, gc+lqr's goal with it and without it differ by exactly the reference's
change since the reset (duc gains d theta_d each tick; nothing else changes). (With the DOB the
goals differ by more: its estimate compares the motor with the goal sent, which differs.)"""

from __future__ import annotations

import numpy as np

from controller import ControllerParams, NoGravity, make_controller

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
