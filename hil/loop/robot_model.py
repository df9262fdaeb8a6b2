"""The controller's model of the robot, from `[model]`: what Sm and the gravity compensator are.

single_link  every joint drives its own link in a vertical plane (the 1-DoF testbed):
             Sm = 1 / I_link (constant), tau_g = m g r cos(theta) per joint
dyros-jet    the humanoid's 12 leg joints on the whole robot (pinocchio, from the URDF):
             the gravity compensator (5)-(8) for the support state, and the
             contact-projected Sm = S M^-1 (I - Pc) S^T of (19), which changes with the
             posture and the support foot: the loop reschedules the LQR gain from it
             (hil/loop/gain_scheduler.py)
"""

from __future__ import annotations

import abc

import numpy as np

from controller import GravityModel, PendulumGravity
from hil.config import Config, ConfigError, robot_description_text


class RobotModel(abc.ABC):
    """The nominal robot a controller is designed on."""

    gravity: GravityModel
    rescheduled: bool  # Sm changes with posture and support: the LQR gain is rescheduled
    # "diagonal" when Sm is diagonal: n 4-state designs give the same gain as one 4n-state
    # design (controller.lqr), in milliseconds instead of a third of a second for 12 joints
    lqr_coupling: str = "full"

    @abc.abstractmethod
    def sm(self, link_angle_rad: np.ndarray, support: object) -> np.ndarray:
        """Sm of (19) at these link angles, for this support state."""

    def set_support(self, support: object) -> None:  # noqa: B027 - only the humanoid has one
        """The support state the gravity compensator splits the weight by."""


class SingleLinks(RobotModel):
    rescheduled = False
    lqr_coupling = "diagonal"

    def __init__(self, n_joints: int, inertia_kg_m2: float, gravity_moment_kg_m: float) -> None:
        self._sm = np.eye(n_joints) / inertia_kg_m2
        # m*r is all the pendulum model needs: pass it as a mass at unit distance
        self.gravity = PendulumGravity(np.full(n_joints, gravity_moment_kg_m), np.ones(n_joints))

    def sm(self, link_angle_rad: np.ndarray, support: object) -> np.ndarray:
        return self._sm


class HumanoidLegs(RobotModel):
    rescheduled = True

    def __init__(self, urdf_text: str, coupling: str, joint_names: tuple[str, ...]) -> None:
        from controller.humanoid import (  # pinocchio: only when a humanoid is configured
            LEG_JOINT_NAMES,
            ContactProjectedInertia,
            HumanoidLegGravity,
            LegModel,
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
        # "closed-chain" designs on the whole Sm (controller/lqr.py); the others as named
        self._coupling = SmCoupling.FULL if coupling == "closed-chain" else SmCoupling(coupling)
        self.lqr_coupling = coupling

    def sm(self, link_angle_rad: np.ndarray, support: object) -> np.ndarray:
        return self._inertia.sm(link_angle_rad, self.support_type(support), self._coupling)

    def set_support(self, support: object) -> None:
        self.gravity.set_support(self.support_type(support))


def robot_model(config: Config) -> RobotModel:
    model = config.model
    if model.robot == "dyros-jet":
        return HumanoidLegs(robot_description_text(config), model.sm_coupling, config.joint_names)
    return SingleLinks(len(config.joints), model.link_inertia_kg_m2, model.gravity_moment_kg_m)
