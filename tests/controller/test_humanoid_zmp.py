"""ZMP from the feet's force/torque sensors, against hand calculations."""

from __future__ import annotations

import numpy as np
import pytest

from controller.humanoid import FootWrench, NoSupportError, zmp_from_foot_wrenches


def rot_z(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def test_one_sensor_kajita_formula() -> None:
    # sensor 0.105 m above the ground at (0.2, 0.1); f = (10, -5, 400) N, tau = (3, -8, 1) N m
    # x = 0.2 + (-tau_y - f_x d) / f_z = 0.2 + (8 - 1.05) / 400 = 0.217375
    # y = 0.1 + (tau_x - f_y d) / f_z = 0.1 + (3 + 0.525) / 400 = 0.1088125
    wrench = FootWrench(
        force_n=np.array([10.0, -5.0, 400.0]),
        torque_nm=np.array([3.0, -8.0, 1.0]),
        position_m=np.array([0.2, 0.1, 0.105]),
        rotation=np.eye(3),
    )
    assert np.allclose(zmp_from_foot_wrenches([wrench]), [0.217375, 0.1088125], atol=1e-12)


def test_two_feet_pure_forces_is_the_weighted_mean() -> None:
    # vertical forces 300 N at (0, 0.128) and 100 N at (0.1, -0.128), no moments:
    # x = (0*300 + 0.1*100)/400 = 0.025; y = (0.128*300 - 0.128*100)/400 = 0.064
    feet = [
        FootWrench(np.array([0, 0, 300.0]), np.zeros(3), np.array([0, 0.128, 0.105]), np.eye(3)),
        FootWrench(np.array([0, 0, 100.0]), np.zeros(3), np.array([0.1, -0.128, 0.105]), np.eye(3)),
    ]
    assert np.allclose(zmp_from_foot_wrenches(feet), [0.025, 0.064], atol=1e-12)


def test_rotated_sensor_frame() -> None:
    # The same physical wrench as in the Kajita case, reported by a sensor turned 90 deg about z:
    # in its frame the world x axis is -y and world y is +x.
    world_force = np.array([10.0, -5.0, 400.0])
    world_torque = np.array([3.0, -8.0, 1.0])
    rotation = rot_z(np.pi / 2)  # world <- sensor
    wrench = FootWrench(
        rotation.T @ world_force, rotation.T @ world_torque, np.array([0.2, 0.1, 0.105]), rotation
    )
    assert np.allclose(zmp_from_foot_wrenches([wrench]), [0.217375, 0.1088125], atol=1e-12)


def test_ground_height_and_lifted_foot() -> None:
    # on a 0.05 m step: the sensor is 0.105 m above the contact plane at z = 0.05
    wrench = FootWrench(
        np.array([20.0, 0, 400.0]), np.zeros(3), np.array([0.0, 0.0, 0.155]), np.eye(3)
    )
    # x = -f_x d / f_z = -20 * 0.105 / 400
    assert zmp_from_foot_wrenches([wrench], ground_height_m=0.05)[0] == pytest.approx(-0.00525)
    airborne = FootWrench(np.array([0, 0, 0.2]), np.zeros(3), np.zeros(3), np.eye(3))
    with pytest.raises(NoSupportError):
        zmp_from_foot_wrenches([airborne])
