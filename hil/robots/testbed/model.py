"""The controller's model of the testbed: every joint drives its own link swinging in a vertical
plane (the 1-DoF testbed, or n independent copies of it): Sm = 1 / I_link (constant),
tau_g = m g r cos(theta) per joint, from `[model] link_inertia_kg_m2` and
`gravity_moment_kg_m`."""

from __future__ import annotations

import numpy as np

from controller import PendulumGravity
from hil.config import Config
from hil.robots.model import RobotModel


class SingleLinks(RobotModel):
    rescheduled = False
    lqr_coupling = "diagonal"

    def __init__(self, n_joints: int, inertia_kg_m2: float, gravity_moment_kg_m: float) -> None:
        self._sm = np.eye(n_joints) / inertia_kg_m2
        # m*r is all the pendulum model needs: pass it as a mass at unit distance
        self.gravity = PendulumGravity(np.full(n_joints, gravity_moment_kg_m), np.ones(n_joints))

    def sm(self, link_angle_rad: np.ndarray, contact: object) -> np.ndarray:
        return self._sm


def single_links(config: Config) -> SingleLinks:
    model = config.model
    return SingleLinks(len(config.joints), model.link_inertia_kg_m2, model.gravity_moment_kg_m)
