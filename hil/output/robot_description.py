"""Which robot a run drove, as viewers see it: its URDF (with shapes to draw), its joints, its
force sensors and the frames they measure in (the ROS 2 bag, run.mcap's 3D view, `hil render`).

A run's robot comes from its meta.json (the configuration it ran):

    a [model] description   that URDF (DYROS-JET's: hil/data/robots/dyros_jet.urdf, a floating
                 base and 28 joints, the 12 leg joints the run logs; a fixed-base robot's: its
                 own). A published URDF without visual geometry (the meshes are not part of
                 this product) gets `with_skeleton_visuals`: a cylinder from each link's
                 origin to each of its child joints, a sphere at each joint, the soles as boxes.
                 Its base floats when its root joint is a floating one.
    none, one joint         hil/data/robots/testbed.urdf (the paper's testbed), its joint named
                 as the run's; several joints without a description have no URDF (frames are
                 left out).

Force sensors: a foot's six columns `<name>_fx_n ... <name>_mz_nm` (the ground's wrench on the
robot in the foot sensor's frame, *_AnkleRoll_Link at the ankle axis: hil/config's
[[force_torque_sensor]]), and the testbed's `contact_force_n`, the block's normal force on the
load, a magnitude: published along +z of the frame "load" (perpendicular to the link in its
plane of motion), its side not measured.
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from drivers.joint_bus import wrench_keys

TESTBED_URDF = "testbed.urdf"
CONTACT_FORCE_COLUMN = "contact_force_n"
CONTACT_FORCE_FRAME = "load"
FOOT_FRAMES = {"left_foot": "L_AnkleRoll_Link", "right_foot": "R_AnkleRoll_Link"}
_SKELETON_RADIUS_M = 0.025
_JOINT_SPHERE_RADIUS_M = 0.035
_SKELETON_RGBA = "0.30 0.45 0.70 1"
_SOLE_RGBA = "0.15 0.15 0.15 1"


@dataclass(frozen=True)
class ForceSensor:
    """A wrench the log holds: its columns (fx fy fz mx my mz; "" where the log has none) and
    the frame it is measured in."""

    name: str
    frame_id: str
    columns: tuple[str, str, str, str, str, str]
    note: str


@dataclass(frozen=True)
class RunRobot:
    """A run's robot for viewers: `urdf` None when there is no description of it."""

    joint_names: tuple[str, ...]
    urdf: str | None  # the description the controller's model reads (kinematics)
    viewer_urdf: str | None  # the same with shapes to draw (published)
    floating_base: bool
    force_sensors: tuple[ForceSensor, ...]
    gear_stiffness_nm_per_rad: np.ndarray  # the controller's K per joint ([model])


def robot_of_run(
    meta: dict[str, Any], joint_names: Sequence[str], sensor_columns: Sequence[str]
) -> RunRobot:
    """The robot of a run from its meta.json, joint names and log sensor columns."""
    model = (meta.get("config") or {}).get("model") or {}
    names = tuple(joint_names)
    sensors = force_sensors(sensor_columns)
    stiffness = _gear_stiffness(model, names)
    if model.get("description"):
        urdf = shipped_or_file(str(model["description"]))
        floating = _has_floating_root(urdf)
        return RunRobot(names, urdf, with_skeleton_visuals(urdf), floating, sensors, stiffness)
    if len(names) != 1:
        return RunRobot(names, None, None, False, sensors, stiffness)
    urdf = _with_joint_named(_shipped(TESTBED_URDF), names[0])
    return RunRobot(names, urdf, urdf, False, sensors, stiffness)


def _with_joint_named(urdf: str, name: str) -> str:
    """A one-joint URDF with its movable joint renamed (the run's own joint name)."""
    movable = [
        j.get("name") for j in ET.fromstring(urdf).findall("joint") if j.get("type") != "fixed"
    ]
    assert len(movable) == 1, "the testbed's URDF has one movable joint"
    return urdf.replace(f'name="{movable[0]}"', f'name="{name}"')


def _has_floating_root(urdf: str) -> bool:
    """The URDF hangs from a floating joint (a legged robot's base), not from the world."""
    return any(joint.get("type") == "floating" for joint in ET.fromstring(urdf).findall("joint"))


def _gear_stiffness(model: dict[str, Any], joint_names: tuple[str, ...]) -> np.ndarray:
    """K per joint as the run's [model] gives it (a [model.joint.NAME] override, else the
    common figure); NaN where the meta has none."""
    common = model.get("stiffness_nm_per_rad")
    overrides = model.get("joint") or {}
    values = []
    for name in joint_names:
        own = (overrides.get(name) or {}).get("stiffness_nm_per_rad")
        value = own if own is not None else common
        values.append(math.nan if value is None else float(value))
    return np.array(values)


def force_sensors(sensor_columns: Sequence[str]) -> tuple[ForceSensor, ...]:
    """The wrenches among a log's sensor columns (module docstring)."""
    columns = set(sensor_columns)
    found: list[ForceSensor] = []
    for column in sensor_columns:
        match = re.fullmatch(r"(.+)_fx_n", column)
        if match is None:
            continue
        name = match.group(1)
        six = wrench_keys(name)
        if set(six) <= columns:
            frame = FOOT_FRAMES.get(name, name)
            note = (
                f"the ground's force [N] and moment [N m] on the robot at {name}'s sensor, in "
                f"{frame} (log.csv {name}_fx_n ... {name}_mz_nm)"
            )
            found.append(ForceSensor(name, frame, six, note))  # type: ignore[arg-type]
    if CONTACT_FORCE_COLUMN in columns:
        note = (
            "the block's normal force on the load [N] (log.csv contact_force_n, a magnitude) "
            f"along +z of {CONTACT_FORCE_FRAME} (perpendicular to the link in its plane of "
            "motion; which side the block is on is the experiment's, not measured)"
        )
        found.append(
            ForceSensor(
                "contact", CONTACT_FORCE_FRAME, ("", "", CONTACT_FORCE_COLUMN, "", "", ""), note
            )
        )
    return tuple(found)


def shipped_or_file(name: str) -> str:
    """A URDF by path, or by the name of one shipped in hil/data/robots (as [model]
    description reads it)."""
    path = Path(name).expanduser()
    if path.is_file():
        return path.read_text()
    return _shipped(name if name.endswith(".urdf") else f"{name}.urdf")


def _shipped(name: str) -> str:
    return resources.files("hil").joinpath("data", "robots", name).read_text()


# --- shapes for viewers -----------------------------------------------------------------------
def with_skeleton_visuals(urdf: str) -> str:
    """The URDF with a <visual> on every link that has none: a cylinder to each child joint,
    a sphere at the link's origin, and each box collision (the soles) as a box."""
    root = ET.fromstring(urdf)
    children: dict[str, list[np.ndarray]] = {}
    for joint in root.findall("joint"):
        parent = joint.find("parent").get("link")  # type: ignore[union-attr]
        origin = joint.find("origin")
        xyz = origin.get("xyz", "0 0 0") if origin is not None else "0 0 0"
        if joint.get("type") != "floating":
            children.setdefault(parent, []).append(np.fromstring(xyz, sep=" "))
    for link in root.findall("link"):
        if link.find("visual") is not None or link.get("name") == "world":
            continue
        name = link.get("name", "")
        _add_visual(link, f"{name}_joint", "0 0 0", "0 0 0", "sphere", _SKELETON_RGBA,
                    radius=_JOINT_SPHERE_RADIUS_M)  # fmt: skip
        for i, end in enumerate(children.get(name, ())):
            length = float(np.linalg.norm(end))
            if length < 1e-3:
                continue
            rpy = _rpy_of_z_towards(end / length)
            _add_visual(link, f"{name}_bone{i}", _xyz(end / 2), _xyz(rpy), "cylinder",
                        _SKELETON_RGBA, radius=_SKELETON_RADIUS_M, length=length)  # fmt: skip
        for collision in link.findall("collision"):
            box = collision.find("geometry/box")
            if box is None:
                continue
            origin = collision.find("origin")
            xyz = origin.get("xyz", "0 0 0") if origin is not None else "0 0 0"
            rpy = origin.get("rpy", "0 0 0") if origin is not None else "0 0 0"
            label = collision.get("name") or f"{name}_box"
            _add_visual(link, label, xyz, rpy, "box", _SOLE_RGBA, size=box.get("size", ""))
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="unicode") + "\n"


def _add_visual(
    link: ET.Element, name: str, xyz: str, rpy: str, shape: str, rgba: str, **size: Any
) -> None:
    visual = ET.SubElement(link, "visual", name=name)
    ET.SubElement(visual, "origin", xyz=xyz, rpy=rpy)
    geometry = ET.SubElement(visual, "geometry")
    ET.SubElement(geometry, shape, {k: str(v) for k, v in size.items()})
    material = ET.SubElement(visual, "material", name=f"{name}_colour")
    ET.SubElement(material, "color", rgba=rgba)


def _xyz(values: np.ndarray) -> str:
    return " ".join(format(float(v), ".6g") for v in values)


def _rpy_of_z_towards(direction: np.ndarray) -> np.ndarray:
    """URDF roll-pitch-yaw (R = Rz Ry Rx) of a frame whose z axis points along `direction`
    (a cylinder's axis): pitch then yaw suffice."""
    x, y, z = direction
    pitch = math.atan2(math.hypot(x, y), z)
    yaw = math.atan2(y, x)
    return np.array([0.0, pitch, yaw])
