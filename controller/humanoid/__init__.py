"""DYROS-JET's legs for the controller (pinocchio): the rigid-body model built from the robot
description, the gravity compensator (5)-(8), Sm of (19) with the support foot's contact, the
ZMP from the feet's force/torque sensors, and standing postures.

Imports nothing of ours outside `controller`.
"""

from controller.humanoid.contact_inertia import ContactProjectedInertia, SmCoupling
from controller.humanoid.gravity import HumanoidLegGravity, SupportForces
from controller.humanoid.leg_model import (
    LAB_WALK_INIT_UPPER_BODY_RAD,
    LEG_JOINT_NAMES,
    N_LEG_JOINTS,
    LegModel,
    UpperBodyPosture,
)
from controller.humanoid.posture import (
    LAB_WALK_INIT_LEG_ANGLES_RAD,
    WALKING_READY_LEG_ANGLES_RAD,
    WALKING_READY_TARGET,
    PostureError,
    PostureTarget,
    SolvedPosture,
    solve_posture,
)
from controller.humanoid.support import (
    LqrContact,
    SmContactRule,
    SupportState,
    lqr_contact_schedule,
)
from controller.humanoid.zmp import FootWrench, NoSupportError, zmp_from_foot_wrenches

__all__ = [
    "LAB_WALK_INIT_LEG_ANGLES_RAD",
    "LAB_WALK_INIT_UPPER_BODY_RAD",
    "LEG_JOINT_NAMES",
    "N_LEG_JOINTS",
    "WALKING_READY_LEG_ANGLES_RAD",
    "WALKING_READY_TARGET",
    "ContactProjectedInertia",
    "FootWrench",
    "HumanoidLegGravity",
    "LegModel",
    "LqrContact",
    "NoSupportError",
    "PostureError",
    "PostureTarget",
    "SmContactRule",
    "SmCoupling",
    "SolvedPosture",
    "SupportForces",
    "SupportState",
    "UpperBodyPosture",
    "lqr_contact_schedule",
    "solve_posture",
    "zmp_from_foot_wrenches",
]
