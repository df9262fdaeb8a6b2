"""The controller's model of the robot, from `[model]`: what Sm and the gravity compensator are.

single_link  every joint drives its own link in a vertical plane (the 1-DoF testbed):
             Sm = 1 / I_link (constant), tau_g = m g r cos(theta) per joint
dyros-jet    the humanoid's 12 leg joints on the whole robot (pinocchio, from the URDF):
             the gravity compensator (5)-(8) for the support state, and the
             contact-projected Sm = S M^-1 (I - Pc) S^T of (19), which changes with the
             posture and the LQR's contact (`[model] sm_contact`: both feet in double support,
             or the paper's one support foot switched at mid double support): the loop
             reschedules the LQR gain from it (hil/loop/gain_scheduler.py)

The LQR's contact is not the gravity compensator's support state: `lqr_contacts` maps a run's
per-tick support states to the contacts Sm is computed for (controller/humanoid/support.py).
"""

from __future__ import annotations

import abc

import numpy as np

from controller import Coupling, GcLoad, GravityModel, PendulumGravity
from hil.config import Config, ConfigError, robot_description_text


class RobotModel(abc.ABC):
    """The nominal robot a controller is designed on."""

    gravity: GravityModel
    rescheduled: bool  # Sm changes with posture and support: the LQR gain is rescheduled
    # "diagonal" when Sm is diagonal: n 4-state designs give the same gain as one 4n-state
    # design (controller.lqr_designs), one batch of n small problems
    lqr_coupling: str = "full"

    @abc.abstractmethod
    def sm(self, link_angle_rad: np.ndarray, contact: object) -> np.ndarray:
        """Sm of (19) at these link angles, for this LQR contact (`lqr_contacts`)."""

    def set_support(self, support: object) -> None:  # noqa: B027 - only the humanoid has one
        """The support state the gravity compensator splits the weight by."""

    def set_planned_motion(self, motion: object) -> None:  # noqa: B027 - only the humanoid's
        """The plan's motion this tick (controller.PlannedMotion) or None: what the gravity
        compensator holds under `[controller] gc_load = "planned-motion"`."""

    def lqr_contacts(self, supports: list[object]) -> list[object]:
        """The LQR's contact per tick for a run's support state per tick (no feet: None)."""
        return [None] * len(supports)


class SingleLinks(RobotModel):
    rescheduled = False
    lqr_coupling = "diagonal"

    def __init__(self, n_joints: int, inertia_kg_m2: float, gravity_moment_kg_m: float) -> None:
        self._sm = np.eye(n_joints) / inertia_kg_m2
        # m*r is all the pendulum model needs: pass it as a mass at unit distance
        self.gravity = PendulumGravity(np.full(n_joints, gravity_moment_kg_m), np.ones(n_joints))

    def sm(self, link_angle_rad: np.ndarray, contact: object) -> np.ndarray:
        return self._sm


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


def robot_model(config: Config) -> RobotModel:
    model = config.model
    if model.robot == "dyros-jet":
        return HumanoidLegs(
            robot_description_text(config),
            model.sm_coupling,
            config.joint_names,
            model.sm_contact,
            model.sm_standing_foot,
            planned_load=config.controller.gc_load is GcLoad.PLANNED_MOTION,
        )
    return SingleLinks(len(config.joints), model.link_inertia_kg_m2, model.gravity_moment_kg_m)
