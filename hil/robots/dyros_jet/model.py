"""The controller's model of DYROS-JET: the humanoid's 12 leg joints on the whole robot
(pinocchio, from the URDF `[model] description`): the gravity compensator (5)-(8) for the
support state, and the contact-projected Sm = S M^-1 (I - Pc) S^T of (19), which changes with
the posture and the LQR's contact (`[model] sm_contact`: both feet in double support, or the
paper's one support foot switched at mid double support): the loop reschedules the LQR gain
from it (hil/loop/gain_scheduler.py)."""

from __future__ import annotations

import numpy as np

from controller import Coupling, GcLoad
from hil.config import Config, ConfigError, robot_description_text
from hil.robots.model import RobotModel


class HumanoidLegs(RobotModel):
    rescheduled = True

    def __init__(
        self,
        urdf_text: str,
        coupling: str,
        joint_names: tuple[str, ...],
        contact_rule: str = "both-feet",
        standing_foot: str = "left",
        planned_load: bool = False,
    ) -> None:
        from controller.humanoid import (  # pinocchio: only when a humanoid is configured
            LEG_JOINT_NAMES,
            ContactProjectedInertia,
            HumanoidLegGravity,
            LegModel,
            LqrContact,
            SmContactRule,
            SmCoupling,
            SupportState,
        )

        if joint_names != LEG_JOINT_NAMES:
            raise ConfigError(
                f"[[joint]] names: DYROS-JET's legs are {list(LEG_JOINT_NAMES)} in this order, "
                f"the configuration names {list(joint_names)}"
            )
        self.support_type = SupportState
        self.leg_model = LegModel(urdf_text)
        self.gravity = HumanoidLegGravity(self.leg_model, SupportState.DOUBLE)
        self._inertia = ContactProjectedInertia(self.leg_model)
        # "closed-chain" designs on the whole Sm (controller/closed_chain.py); the others as named
        self._coupling = (
            SmCoupling.FULL if coupling == Coupling.CLOSED_CHAIN else SmCoupling(str(coupling))
        )
        self.lqr_coupling = coupling
        self._contact_rule = SmContactRule(contact_rule)
        self._standing_foot = LqrContact(f"{standing_foot}-foot")
        self._contact_type = LqrContact
        self._planned_load = planned_load  # [controller] gc_load = "planned-motion"

    def sm(self, link_angle_rad: np.ndarray, contact: object) -> np.ndarray:
        return self._inertia.sm(link_angle_rad, self._contact_type(contact), self._coupling)

    def set_support(self, support: object) -> None:
        self.gravity.set_support(self.support_type(support))

    def set_planned_motion(self, motion: object) -> None:
        if not self._planned_load:
            return
        if motion is None:
            self.gravity.set_planned_load(None, None)
        else:
            self.gravity.set_planned_load(motion.com_acceleration_mps2, motion.support_split)

    def lqr_contacts(self, supports: list[object]) -> list[object]:
        from controller.humanoid import lqr_contact_schedule

        states = [self.support_type(s) for s in supports]
        return list(lqr_contact_schedule(states, self._contact_rule, self._standing_foot))


def humanoid_legs(config: Config) -> HumanoidLegs:
    model = config.model
    return HumanoidLegs(
        robot_description_text(config),
        model.sm_coupling,
        config.joint_names,
        model.sm_contact,
        model.sm_standing_foot,
        planned_load=config.controller.gc_load is GcLoad.PLANNED_MOTION,
    )
