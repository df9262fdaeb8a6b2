"""The zero-moment point from the feet's force/torque sensors.

Each foot's sensor measures the wrench (f, tau) the ground exerts on the robot through that foot,
expressed in the sensor's frame, tau about the sensor's origin. With the sensor's pose in the
world (position p, rotation R: world <- sensor) the world wrench is f_w = R f, tau_w = R tau.
The moment of all feet's wrenches about a point z = (x, y, h) of the ground plane is

    M(z) = sum_i [ tau_w,i + (p_i - z) x f_w,i ]

and the ZMP is the point where the horizontal components of M vanish:

    x = sum_i ( p_ix f_iz - (p_iz - h) f_ix - tau_iy ) / sum_i f_iz
    y = sum_i ( p_iy f_iz - (p_iz - h) f_iy + tau_ix ) / sum_i f_iz

(for one sensor at height d above the ground: x = (-tau_y - f_x d) / f_z,
y = (tau_x - f_y d) / f_z, Kajita et al., "Introduction to Humanoid Robotics", Sec. 3.3).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class FootWrench:
    """One foot sensor's reading (sensor frame) and the sensor's pose in the world.

    force_n, torque_nm: the ground's wrench on the robot, in the sensor frame, about its origin.
    position_m: the sensor origin in the world. rotation: world <- sensor (3 x 3).
    """

    force_n: np.ndarray
    torque_nm: np.ndarray
    position_m: np.ndarray
    rotation: np.ndarray


class NoSupportError(ValueError):
    """The feet carry (almost) no vertical load: the ZMP is undefined (the robot is airborne)."""


def zmp_from_foot_wrenches(
    wrenches: Sequence[FootWrench],
    ground_height_m: float = 0.0,
    min_vertical_force_n: float = 1.0,
) -> np.ndarray:
    """The ZMP (x, y) [m] on the plane z = ground_height_m from the feet's wrenches."""
    if not wrenches:
        raise ValueError("zmp_from_foot_wrenches needs at least one foot wrench")
    moment_x = moment_y = vertical = 0.0
    for wrench in wrenches:
        rotation = np.asarray(wrench.rotation, dtype=float)
        force = rotation @ np.asarray(wrench.force_n, dtype=float)
        torque = rotation @ np.asarray(wrench.torque_nm, dtype=float)
        px, py, pz = np.asarray(wrench.position_m, dtype=float)
        height = pz - ground_height_m
        moment_x += px * force[2] - height * force[0] - torque[1]
        moment_y += py * force[2] - height * force[1] + torque[0]
        vertical += force[2]
    if vertical < min_vertical_force_n:
        raise NoSupportError(
            f"total vertical force {vertical:.3g} N < {min_vertical_force_n} N: no ZMP"
        )
    return np.array([moment_x / vertical, moment_y / vertical])
