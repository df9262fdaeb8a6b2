"""The walking-ready posture data and the posture IK."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from controller.humanoid import (
    LAB_WALK_INIT_LEG_ANGLES_RAD,
    WALKING_READY_LEG_ANGLES_RAD,
    WALKING_READY_TARGET,
    LegModel,
    PostureError,
    PostureTarget,
    solve_posture,
)

URDF_PATH = Path(__file__).resolve().parents[2] / "hil" / "data" / "robots" / "dyros_jet.urdf"


@pytest.fixture(scope="module")
def model() -> LegModel:
    return LegModel(URDF_PATH.read_text())


def test_stated_angles_are_the_ik_solution(model: LegModel) -> None:
    solved = solve_posture(model, WALKING_READY_TARGET, np.array(LAB_WALK_INIT_LEG_ANGLES_RAD))
    assert np.allclose(solved.leg_angles_rad, WALKING_READY_LEG_ANGLES_RAD, atol=1e-9)


def test_walking_ready_posture_meets_its_definition(model: LegModel) -> None:
    angles = np.array(WALKING_READY_LEG_ANGLES_RAD)
    q = model.standing_configuration(angles, side=0)
    model.update_kinematics(q)
    left, right = model.sole_placement(0), model.sole_placement(1)
    # both soles flat, on the same ground, 0.2556 m apart side by side
    assert np.allclose(right.rotation, np.eye(3), atol=1e-9)
    assert right.translation[2] == pytest.approx(0.0, abs=1e-9)
    assert np.allclose(left.translation - right.translation, [0, 0.2556, 0], atol=1e-9)
    # CoM over the middle of the sole centres; pelvis upright at 0.87 m
    middle = 0.5 * (left.translation + right.translation)
    assert np.allclose(model.centre_of_mass(q)[:2], middle[:2], atol=1e-9)
    assert np.allclose(q[3:7], [0, 0, 0, 1], atol=1e-9)
    assert q[2] == pytest.approx(0.87, abs=1e-9)
    # bent knees as in the lab's walking init (42 deg), feet flat: pitch angles sum to zero
    assert np.rad2deg(angles[3]) == pytest.approx(42.2, abs=0.1)
    assert angles[2] + angles[3] + angles[4] == pytest.approx(0.0, abs=1e-9)


def test_lab_posture_puts_the_com_ahead_of_the_feet(model: LegModel) -> None:
    """Why the walking-ready posture differs from the lab's angles (stated in posture.py)."""
    q = model.standing_configuration(np.array(LAB_WALK_INIT_LEG_ANGLES_RAD), side=0)
    model.update_kinematics(q)
    sole_x = model.sole_placement(0).translation[0]
    assert model.centre_of_mass(q)[0] - sole_x == pytest.approx(0.040, abs=0.001)


def test_unreachable_target_raises(model: LegModel) -> None:
    target = PostureTarget((0, 0.1278, 0), (0, -0.1278, 0), (0, 0), pelvis_height_m=1.5)
    with pytest.raises(PostureError):
        solve_posture(model, target, np.array(LAB_WALK_INIT_LEG_ANGLES_RAD), max_iterations=30)
