"""The linearised emulated robot (sim_backend/humanoid/linear.py) against the nonlinear one: a
small goal step on one joint, less the same robot's own drift (a twin without the step)."""

from __future__ import annotations

import numpy as np
import pytest

from controller.humanoid import WALKING_READY_LEG_ANGLES_RAD, SupportState
from sim_backend.humanoid.linear import Friction, linearise
from sim_backend.humanoid.params import RobotTruthParams
from sim_backend.servo import RAD_PER_PULSE
from tests.support.humanoid_loop import settled_robot

PERIOD_S = 0.005
STEP_PULSES = 160  # 2.0 mrad
ANKLE_PITCH = 4


@pytest.mark.parametrize("friction", [Friction.STUCK, Friction.SLIDING])
def test_a_goal_step_follows_the_tick_model(friction: Friction) -> None:
    """With the gearbox friction (stuck about rest) and without it (the same model linearised
    with MuJoCo's frictionloss off: the robot is built without it), the motor and the links of
    the stepped ankle and of the knee follow the tick model to 1 % of the largest response over
    200 ms."""
    truth = (
        RobotTruthParams(gearbox_coulomb_friction_nm=0.0) if friction is Friction.SLIDING else None
    )
    angles = np.array(WALKING_READY_LEG_ANGLES_RAD)
    robot = settled_robot(angles, SupportState.DOUBLE, truth=truth, seconds=1.0)
    twin = settled_robot(angles, SupportState.DOUBLE, truth=truth, seconds=1.0)
    model = linearise(robot, PERIOD_S, friction)
    device = robot.tables[ANKLE_PITCH]
    device.set_item("Goal Position", device.item("Goal Position") + STEP_PULSES)
    goal = np.zeros(12)
    goal[ANKLE_PITCH] = STEP_PULSES * RAD_PER_PULSE
    z = np.zeros(model.size)
    predicted, measured = [], []
    for _ in range(40):
        robot.advance(PERIOD_S)
        twin.advance(PERIOD_S)
        z = model.f @ z + model.g @ goal
        predicted.append(np.concatenate([model.motor_angle @ z, model.link_angle @ z]))
        measured.append(
            np.concatenate(
                [
                    robot.plant.motor_angle_rad - twin.plant.motor_angle_rad,
                    robot.plant.link_angle_rad - twin.plant.link_angle_rad,
                ]
            )
        )
    predicted, measured = np.array(predicted), np.array(measured)
    scale = np.abs(measured).max()
    assert scale > 1e-4  # the step moved the robot
    assert np.abs(predicted - measured).max() < 0.01 * scale
