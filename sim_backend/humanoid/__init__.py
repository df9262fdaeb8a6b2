"""The emulated DYROS-JET legs: a MuJoCo plant generated from the robot's URDF text, with 12
flexible joints (rotor hinge -> elastic gear hinge -> link), foot force/torque sensors and a
push on the pelvis, driven by 12 H54 firmware models (`EmulatedRobot`).

This is the truth of a humanoid run; its parameters (`RobotTruthParams`) can differ from the
controller's nominal model. Imports nothing of `drivers`.
"""

from sim_backend.humanoid.params import (
    DYROS_JET_LEG_TORQUE_LIMIT_REGISTER,
    LAB_KNEE_POSITION_GAIN_REGISTER,
    LAB_WALK_INIT_UPPER_BODY_RAD,
    LEG_JOINT_NAMES,
    N_LEG_JOINTS,
    ContactParams,
    RobotTruthParams,
    leg_eeprom_overrides,
)
from sim_backend.humanoid.plant import HumanoidPlant
from sim_backend.humanoid.robot import EmulatedRobot, PelvisPush

__all__ = [
    "DYROS_JET_LEG_TORQUE_LIMIT_REGISTER",
    "LAB_KNEE_POSITION_GAIN_REGISTER",
    "LAB_WALK_INIT_UPPER_BODY_RAD",
    "LEG_JOINT_NAMES",
    "N_LEG_JOINTS",
    "ContactParams",
    "EmulatedRobot",
    "HumanoidPlant",
    "PelvisPush",
    "RobotTruthParams",
    "leg_eeprom_overrides",
]
