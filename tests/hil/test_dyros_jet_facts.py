"""DYROS-JET's facts live once per side of the product: the controller's model
(controller/humanoid/leg_model.py) and the emulator's truth (sim_backend/humanoid/params.py)
may not import each other (the emulated robot is the truth, the controller's model nominal:
separate objects from the same published figures), and each runs without hil. So each side
holds one copy of the leg joints' names and order and of the upper body's locked posture, and
this test keeps the two equal to each other and to DYROS-JET's built-in configuration."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import controller.humanoid.leg_model as controller_side
import sim_backend.humanoid.params as emulator_side
from hil.config import load_config, robot_description_text
from hil.vocabulary import Robot


def test_the_leg_joints_are_the_same_on_both_sides_and_in_the_configuration() -> None:
    config = load_config(robot=Robot.DYROS_JET)
    assert controller_side.LEG_JOINT_NAMES == emulator_side.LEG_JOINT_NAMES
    assert config.joint_names == controller_side.LEG_JOINT_NAMES
    assert controller_side.FOOT_LINK_NAMES == emulator_side.FOOT_LINK_NAMES
    urdf = ET.fromstring(robot_description_text(config))
    revolute = {j.get("name") for j in urdf.findall("joint") if j.get("type") == "revolute"}
    assert set(controller_side.LEG_JOINT_NAMES) <= revolute


def test_the_upper_body_is_locked_at_the_same_posture_on_both_sides() -> None:
    assert dict(controller_side.LAB_WALK_INIT_UPPER_BODY_RAD) == dict(
        emulator_side.LAB_WALK_INIT_UPPER_BODY_RAD
    )
    urdf = ET.fromstring(robot_description_text(load_config(robot=Robot.DYROS_JET)))
    revolute = {j.get("name") for j in urdf.findall("joint") if j.get("type") == "revolute"}
    upper = revolute - set(controller_side.LEG_JOINT_NAMES)
    assert set(controller_side.LAB_WALK_INIT_UPPER_BODY_RAD) == upper
