"""The controller's DYROS-JET leg model (pinocchio) against the published figures."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from controller.humanoid import (
    LAB_WALK_INIT_UPPER_BODY_RAD,
    LEG_JOINT_NAMES,
    LegModel,
    UpperBodyPosture,
)

URDF_PATH = Path(__file__).resolve().parents[2] / "hil" / "data" / "robots" / "dyros_jet.urdf"


@pytest.fixture(scope="module")
def urdf_text() -> str:
    return URDF_PATH.read_text()


@pytest.fixture(scope="module")
def model(urdf_text: str) -> LegModel:
    return LegModel(urdf_text)


def test_floating_base_and_twelve_legs(model: LegModel) -> None:
    assert model.nq == 7 + 12 and model.nv == 6 + 12
    # the URDF's "virtual" joint is the free flyer; no second one was stacked
    assert model.model.names[1] == "virtual" and model.model.joints[1].nv == 6
    names = [model.model.names[i] for i in range(2, model.model.njoints)]
    assert sorted(names) == sorted(LEG_JOINT_NAMES)


def test_total_mass_is_the_published_sum(model: LegModel, urdf_text: str) -> None:
    root = ET.fromstring(urdf_text)
    published = sum(float(m.get("value")) for m in root.iter("mass"))
    assert published == pytest.approx(49.95809, abs=1e-9)
    # locking the upper body keeps its mass (welded into the pelvis)
    assert model.total_mass_kg == pytest.approx(published, abs=1e-9)


def test_lab_leg_order_maps_to_pinocchio(model: LegModel) -> None:
    angles = np.arange(12) * 0.01
    q = model.configuration(angles)
    for index, name in enumerate(LEG_JOINT_NAMES):
        joint = model.model.joints[model.model.getJointId(name)]
        assert q[joint.idx_q] == pytest.approx(angles[index])
    assert np.allclose(model.leg_angles(q), angles)


def test_sole_frame_is_the_bottom_of_the_urdf_box(model: LegModel) -> None:
    # all angles zero, pelvis at the origin: by the published joint origins the left ankle is at
    # hip (0, 0.105, -0.1119) + knee (0.1515, 0, -0.339) + ankle (0.06, 0, -0.368); the sole's
    # bottom centre is (0.01, 0, -0.095 - 0.01) below it (the box in the URDF).
    model.update_kinematics(model.configuration(np.zeros(12)))
    ankle = np.array([0.0 + 0.1515 + 0.06, 0.105, -0.1119 - 0.339 - 0.368])
    assert np.allclose(model.sole_placement(0).translation, ankle + [0.01, 0, -0.105], atol=1e-12)
    assert np.allclose(model.sole_placement(1).translation, ankle * [1, -1, 1] + [0.01, 0, -0.105])


def test_upper_body_locked_where_stated(urdf_text: str) -> None:
    root = ET.fromstring(urdf_text)
    for name, angle in LAB_WALK_INIT_UPPER_BODY_RAD.items():
        limit = root.find(f"joint[@name='{name}']/limit")
        assert float(limit.get("lower")) <= angle <= float(limit.get("upper")), name
    # a different lock posture moves the CoM (the arms are 10 kg)
    straight = dict(LAB_WALK_INIT_UPPER_BODY_RAD, L_ElbowRoll=0.0, R_ElbowRoll=0.0)
    other = LegModel(urdf_text, UpperBodyPosture(straight))
    default = LegModel(urdf_text)
    q = default.configuration(np.zeros(12))
    assert np.linalg.norm(other.centre_of_mass(q) - default.centre_of_mass(q)) > 1e-3


def test_missing_upper_body_angle_is_refused(urdf_text: str) -> None:
    partial = dict(LAB_WALK_INIT_UPPER_BODY_RAD)
    del partial["WaistYaw"]
    with pytest.raises(ValueError, match="WaistYaw"):
        LegModel(urdf_text, UpperBodyPosture(partial))


def test_flat_sole_rotation(model: LegModel) -> None:
    angles = np.deg2rad([5, 3, -20, 40, -15, 2, -4, -1, 10, -30, 25, 3])
    for side in (0, 1):
        q = model.standing_configuration(angles, side)
        model.update_kinematics(q)
        sole = model.sole_placement(side)
        assert np.allclose(sole.rotation, np.eye(3), atol=1e-12)
        assert np.allclose(sole.translation, 0.0, atol=1e-12)
    assert np.isclose(pin.Quaternion(q[3:7]).norm(), 1.0)


def test_standing_configuration_leaves_the_frames_at_its_q(model: LegModel) -> None:
    # the ZMP from the feet's sensors needs the sensors' placement at the standing q, not at the
    # q before its base was moved under the sole
    angles = np.deg2rad([0, 2, -15, 35, -20, -2, 0, -2, 15, -35, 20, 2])
    q = model.standing_configuration(angles, side=1)
    assert np.allclose(model.sole_placement(1).translation, 0.0, atol=1e-12)
    sensor = model.ft_sensor_placement(0).translation.copy()
    model.update_kinematics(q)
    assert np.allclose(sensor, model.ft_sensor_placement(0).translation, atol=1e-12)
