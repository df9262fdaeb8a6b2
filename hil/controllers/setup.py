"""A run's `ControllerSetup` from the configuration: what every controller is built from."""

from __future__ import annotations

import numpy as np

from hil.config import Config
from hil.controllers.contract import ControllerSetup
from hil.controllers.paper_factory import joint_params
from hil.controllers.robot_model import RobotModel


def controller_setup(
    config: Config,
    period_s: float,
    robot: RobotModel,
    start_reference_rad: np.ndarray,
    start_contact: object,
) -> ControllerSetup:
    """The setup of the configured robot for a run that starts at `start_reference_rad`."""
    joints = joint_params(config)
    return ControllerSetup(
        joint_names=tuple(config.joint_names),
        period_s=period_s,
        stiffness_nm_per_rad=joints.stiffness_nm_per_rad,
        damping_nms_per_rad=joints.damping_nms_per_rad,
        servo_gain_per_s=joints.servo_gain_per_s,
        robot=robot,
        start_reference_rad=np.array(start_reference_rad, dtype=float),
        start_contact=start_contact,
        config=config,
    )
