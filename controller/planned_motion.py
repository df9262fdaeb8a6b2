"""What a planned motion (a walk's pattern) tells the controller at one tick, beyond the reference.

The paper's controller sees the reference theta_d only: its gravity compensator (5)-(8) holds
the static weight ("we assume ... a slow walking motion", Sec. III-C) and its LQR (21) takes
d theta_d / dt ~ 0. A walking pattern knows more, exactly and without noise: how the reference
moves and what the ground must push. `PlannedMotion` carries that to the two blocks that can
use it (ours, beyond the 2018 paper, in the spirit of the lab's ICRA 2019 pattern generator that
models the compliant position tracking: M. Kim, D. Lim, J. Park, "Online Walking Pattern
Generation for Humanoid Robot with Compliant Motion Control"):

    reference_increment_rad            theta_plan(k) - theta_plan(k-1) per joint [rad]
    reference_velocity_increment_rad_s (theta_plan(k) - 2 theta_plan(k-1) + theta_plan(k-2)) / dt,
                                       the increment of the planned link velocity [rad/s]:
        the LQR's derivative-form state increment of a robot that follows the plan, so that
        the LQR corrects about the plan's motion instead of braking it
        (`controller.controllers`, reference_feedforward);
    com_acceleration_mps2              the planned CoM acceleration (3,) [m/s^2]
    support_split                      mu of (6)-(7) where the plan's ZMP lies between the feet
                                       (0 left, 1 right), or None:
        the ground reaction the plan needs, m (g - a_com) through the planned ZMP, in (5)-(7)
        instead of the static weight through the CoM (`controller.humanoid.HumanoidLegGravity`).
The humanoid fields are None where no CoM or feet are planned.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np


class GcLoad(enum.StrEnum):
    """What the gravity compensator (5)-(7) holds where a motion is planned: the static weight
    split at the CoM (the paper's), or the ground reaction the plan needs split at its ZMP."""

    WEIGHT = "weight"
    PLANNED_MOTION = "planned-motion"


@dataclass(frozen=True)
class PlannedMotion:
    """The plan at one tick (module docstring). Arrays are not copied: do not change them."""

    reference_increment_rad: np.ndarray
    reference_velocity_increment_rad_s: np.ndarray
    com_acceleration_mps2: np.ndarray | None = None
    support_split: float | None = None

    def __post_init__(self) -> None:
        if np.shape(self.reference_increment_rad) != np.shape(
            self.reference_velocity_increment_rad_s
        ):
            raise ValueError("the reference's increment and velocity increment differ in shape")
        if self.com_acceleration_mps2 is not None and np.shape(self.com_acceleration_mps2) != (3,):
            raise ValueError("com_acceleration_mps2 must have 3 entries")
        split = self.support_split
        if split is not None and not (math.isfinite(split) and 0.0 <= split <= 1.0):
            raise ValueError(f"support_split must be in [0, 1], got {split}")
