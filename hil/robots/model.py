"""The controller's model of a robot (`RobotModel`): what Sm of (19) and the gravity compensator
(5)-(8) are on it. Each robot's folder makes its own (hil/robots/<name>/model.py); the loop and
the controllers see only this face.

The LQR's contact is not the gravity compensator's support state: `lqr_contacts` maps a run's
per-tick support states to the contacts Sm is computed for (the humanoid's feet; None for a
robot without feet).
"""

from __future__ import annotations

import abc

import numpy as np

from controller import GravityModel


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
