"""The controller's model of a fixed-base robot of flexible joints, from its URDF (`[model]
description`; controller/fixed_base.py): the gravity compensator's tau_g = g(theta), the joints'
generalised gravity (coupled: each joint carries every link beyond it), and Sm of (19) with no
contact, M(theta)^-1, both changing with the posture: the loop reschedules the LQR's gain from
it (hil/loop/gain_scheduler.py), on its diagonal or the full matrix (`[model] sm_coupling`)."""

from __future__ import annotations

import numpy as np

from controller import Coupling
from hil.config import Config, robot_description_text
from hil.robots.model import RobotModel


class FixedBaseLinks(RobotModel):
    rescheduled = True

    def __init__(
        self,
        urdf_text: str,
        joint_names: tuple[str, ...],
        locked_angles_rad: dict[str, float],
        coupling: str,
    ) -> None:
        from controller.fixed_base import (  # pinocchio: only when such a robot is configured
            FixedBaseGravity,
            FixedBaseInertia,
            FixedBaseModel,
        )

        self.fixed_base = FixedBaseModel(urdf_text, joint_names, locked_angles_rad)
        self.gravity = FixedBaseGravity(self.fixed_base)
        self._inertia = FixedBaseInertia(self.fixed_base)
        self._diagonal = Coupling(coupling) is Coupling.DIAGONAL
        self.lqr_coupling = coupling

    def sm(self, link_angle_rad: np.ndarray, contact: object) -> np.ndarray:
        return self._inertia.sm(link_angle_rad, diagonal=self._diagonal)


def fixed_base_links(config: Config) -> FixedBaseLinks:
    model = config.model
    return FixedBaseLinks(
        robot_description_text(config),
        config.joint_names,
        dict(model.locked_joint_angles_rad),
        model.sm_coupling,
    )
