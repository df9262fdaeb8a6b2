"""The flexible joints' time step: a push on the pelvis at 2, 1 and 0.5 ms against 0.1 ms.

The emulated robot stands in the walking-ready posture with the GC feed-forward; a 150 N push
forward for 0.1 s moves the links by ~37 mrad. The firmware runs once per physics step, so its
discretisation converges together with MuJoCo's `implicitfast`. Measured (link angles every
5 ms over 1.5 s, largest error over all 12 joints): 2 ms 19 mrad, 1 ms 2.3 mrad, 0.5 ms
1.0 mrad: first order in the step, and the 1 ms default is within 2.5 mrad (7 % of the
excursion).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from controller.humanoid import (
    WALKING_READY_LEG_ANGLES_RAD,
    HumanoidLegGravity,
    LegModel,
    SupportState,
)
from sim_backend.dynamixel.device import H54Device
from sim_backend.humanoid.params import RobotTruthParams, leg_eeprom_overrides
from sim_backend.humanoid.robot import EmulatedRobot, PelvisPush
from sim_backend.servo import RAD_PER_PULSE

URDF_PATH = Path(__file__).resolve().parents[2] / "hil" / "data" / "robots" / "dyros_jet.urdf"
READY = np.array(WALKING_READY_LEG_ANGLES_RAD)
PERIOD_S = 0.005
DURATION_S = 1.5


def link_trajectory(urdf_text: str, goal: np.ndarray, timestep_s: float) -> np.ndarray:
    devices = [H54Device(i + 1, eeprom_overrides=leg_eeprom_overrides()) for i in range(12)]
    robot = EmulatedRobot(
        urdf_text,
        devices,
        truth=RobotTruthParams(physics_timestep_s=timestep_s),
        initial_leg_angles_rad=READY,
    )
    for index, device in enumerate(devices):
        device.set_item("Torque Enable", 1)
        device.set_item("Goal Position", round(goal[index] / RAD_PER_PULSE))
    robot.pushes.append(PelvisPush(start_s=0.5, duration_s=0.1, force_n=(150.0, 0.0, 0.0)))
    robot.start_scenario()
    samples = []
    for _ in range(round(DURATION_S / PERIOD_S)):
        robot.advance(PERIOD_S)
        samples.append(robot.plant.link_angle_rad)
    return np.array(samples)


@pytest.mark.slow  # ~10 s: the 0.1 ms reference is 15,000 steps
def test_flexible_joints_converge_with_the_step() -> None:
    urdf_text = URDF_PATH.read_text()
    leg_model = LegModel(urdf_text)
    gravity = HumanoidLegGravity(leg_model, SupportState.DOUBLE)
    goal = READY + gravity.gravity_torque(READY) / 2000.0
    reference = link_trajectory(urdf_text, goal, 0.0001)
    excursion = np.abs(reference - reference[0]).max()
    assert excursion > 0.02  # the push moved the legs
    errors = {
        dt: np.abs(link_trajectory(urdf_text, goal, dt) - reference).max()
        for dt in (0.002, 0.001, 0.0005)
    }
    assert errors[0.001] < 3e-3
    assert errors[0.0005] < 1.5e-3
    assert errors[0.0005] < errors[0.001] < errors[0.002]
    # first order: halving the step roughly halves the error
    assert 1.5 < errors[0.001] / errors[0.0005] < 3.5
