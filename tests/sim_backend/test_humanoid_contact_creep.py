"""The emulated soles stick when loaded well inside their friction cone (ContactParams).

Standing in the walking-ready posture with the gravity-compensated goals held (no feedback),
the splayed legs push each sole outward by ~4 N against mu Fz = 245 N: a sole must not move.
MuJoCo's soft friction at its own defaults (pyramidal cone, impratio 1:
`ContactParams.creeping()`) lets the feet spread at ~0.5 mm/s; the emulator's default
(`ContactParams.sticking()`: elliptic, impratio 100) holds them.
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
from sim_backend.humanoid.params import ContactParams, RobotTruthParams, leg_eeprom_overrides
from sim_backend.humanoid.robot import EmulatedRobot
from sim_backend.servo import RAD_PER_PULSE

URDF = Path(__file__).resolve().parents[2] / "hil" / "data" / "robots" / "dyros_jet.urdf"
READY = np.array(WALKING_READY_LEG_ANGLES_RAD)


def _feet_spread_m(contact: ContactParams, seconds: float) -> tuple[float, float]:
    """(change of the soles' lateral distance [m], smaller friction-cone margin mu Fz / |Fy|)."""
    urdf = URDF.read_text()
    tau = HumanoidLegGravity(LegModel(urdf), SupportState.DOUBLE).gravity_torque(READY)
    goal = READY + tau / 2000.0
    devices = [H54Device(i + 1, eeprom_overrides=leg_eeprom_overrides()) for i in range(12)]
    robot = EmulatedRobot(
        urdf, devices, truth=RobotTruthParams(contact=contact), initial_leg_angles_rad=READY
    )
    for index, device in enumerate(devices):
        device.set_item("Torque Enable", 1)
        device.set_item("Goal Position", round(goal[index] / RAD_PER_PULSE))
    robot.advance(0.3)  # settle onto the springs
    before = [robot.plant.ft_sensor_pose(side)[0][1] for side in (0, 1)]
    robot.advance(seconds)
    after = [robot.plant.ft_sensor_pose(side)[0][1] for side in (0, 1)]
    margin = min(
        contact.friction * robot.foot_wrench(side)[0][2] / abs(robot.foot_wrench(side)[0][1])
        for side in (0, 1)
    )
    return (after[0] - after[1]) - (before[0] - before[1]), margin


@pytest.mark.slow
def test_loaded_soles_do_not_creep() -> None:
    assert ContactParams() == ContactParams.sticking()  # the emulator's default
    spread, margin = _feet_spread_m(ContactParams(), 1.0)
    assert margin > 20  # deep inside the friction cone: a real sole sticks
    assert abs(spread) < 5e-5
    creeping_spread, _ = _feet_spread_m(ContactParams.creeping(), 1.0)
    assert creeping_spread > 3e-4  # MuJoCo's soft friction: the feet spread ~0.5 mm per second


def test_contact_params_refuse_impratio_without_elliptic_cone() -> None:
    with pytest.raises(ValueError):
        ContactParams(friction_cone="pyramidal", friction_impedance_ratio=100.0)
    with pytest.raises(ValueError):
        ContactParams(friction_impedance_ratio=0.5)
    with pytest.raises(ValueError):
        ContactParams(friction_cone="pyramidal")  # impratio 100 needs the elliptic cone
