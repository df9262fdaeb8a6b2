"""The emulator's reading of a URDF robot description: links, joints, the feet's sole boxes.

Only what the MuJoCo generator needs: per link its inertial (mass, CoM, full inertia tensor in
the link frame) and box collisions; per joint its type, parent, child, origin and axis. The URDF
convention for `rpy` is fixed-axis roll-pitch-yaw: R = Rz(yaw) Ry(pitch) Rx(roll).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Inertial:
    """A link's mass [kg], CoM [m] and inertia tensor about the CoM [kg m^2], link frame."""

    mass_kg: float
    com_m: np.ndarray
    inertia_kg_m2: np.ndarray  # 3 x 3


@dataclass(frozen=True)
class BoxCollision:
    """A box collision: centre [m] and full size [m] in the link frame (no rotation)."""

    name: str
    centre_m: np.ndarray
    size_m: np.ndarray


@dataclass(frozen=True)
class Link:
    name: str
    inertial: Inertial | None
    boxes: tuple[BoxCollision, ...] = ()


@dataclass(frozen=True)
class Joint:
    """A URDF joint: origin = child frame in the parent frame; axis in the child (joint) frame."""

    name: str
    kind: str  # "revolute", "continuous", "fixed", "floating"
    parent: str
    child: str
    origin_xyz_m: np.ndarray
    origin_rotation: np.ndarray  # 3 x 3, parent <- child
    axis: np.ndarray


@dataclass(frozen=True)
class RobotDescription:
    """All links and joints of a URDF, and the tree as parent -> child joints."""

    name: str
    links: dict[str, Link]
    joints: dict[str, Joint]
    children: dict[str, tuple[str, ...]] = field(default_factory=dict)  # link -> joint names

    @property
    def root_link(self) -> str:
        child_links = {joint.child for joint in self.joints.values()}
        roots = [name for name in self.links if name not in child_links]
        if len(roots) != 1:
            raise ValueError(f"the robot description must have one root link, found {roots}")
        return roots[0]

    def total_mass_kg(self) -> float:
        return sum(link.inertial.mass_kg for link in self.links.values() if link.inertial)


_INERTIA_KEYS = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")


def rotation_from_rpy(rpy: np.ndarray) -> np.ndarray:
    """URDF rpy (fixed axes X, Y, Z) -> rotation matrix Rz(y) Ry(p) Rx(r)."""
    roll, pitch, yaw = rpy
    cr, sr, cp, sp, cy, sy = (
        np.cos(roll),
        np.sin(roll),
        np.cos(pitch),
        np.sin(pitch),
        np.cos(yaw),
        np.sin(yaw),
    )
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def _vector(element: ET.Element | None, attribute: str, default: str) -> np.ndarray:
    text = element.get(attribute, default) if element is not None else default
    return np.array([float(value) for value in text.split()])


def parse_urdf(urdf_text: str) -> RobotDescription:
    """Parse URDF text (see the module docstring for what is kept)."""
    root = ET.fromstring(urdf_text)
    links: dict[str, Link] = {}
    for element in root.findall("link"):
        inertial = None
        inertial_element = element.find("inertial")
        if inertial_element is not None:
            origin = inertial_element.find("origin")
            rotation = rotation_from_rpy(_vector(origin, "rpy", "0 0 0"))
            tensor = inertial_element.find("inertia")
            assert tensor is not None, f"link {element.get('name')}: inertial without inertia"
            moments = {key: float(tensor.get(key, "0")) for key in _INERTIA_KEYS}
            local = np.array(
                [
                    [moments["ixx"], moments["ixy"], moments["ixz"]],
                    [moments["ixy"], moments["iyy"], moments["iyz"]],
                    [moments["ixz"], moments["iyz"], moments["izz"]],
                ]
            )
            mass = inertial_element.find("mass")
            inertial = Inertial(
                mass_kg=float(mass.get("value")) if mass is not None else 0.0,
                com_m=_vector(origin, "xyz", "0 0 0"),
                inertia_kg_m2=rotation @ local @ rotation.T,
            )
        boxes = []
        for index, collision in enumerate(element.findall("collision")):
            box = collision.find("geometry/box")
            if box is None:
                continue
            origin = collision.find("origin")
            if np.any(_vector(origin, "rpy", "0 0 0") != 0):
                raise ValueError(f"link {element.get('name')}: rotated boxes are not supported")
            boxes.append(
                BoxCollision(
                    name=collision.get("name", f"{element.get('name')}_box{index}"),
                    centre_m=_vector(origin, "xyz", "0 0 0"),
                    size_m=_vector(box, "size", "0 0 0"),
                )
            )
        links[element.get("name", "")] = Link(element.get("name", ""), inertial, tuple(boxes))
    joints: dict[str, Joint] = {}
    children: dict[str, list[str]] = {name: [] for name in links}
    for element in root.findall("joint"):
        origin = element.find("origin")
        parent = element.find("parent")
        child = element.find("child")
        assert parent is not None and child is not None
        joint = Joint(
            name=element.get("name", ""),
            kind=element.get("type", ""),
            parent=parent.get("link", ""),
            child=child.get("link", ""),
            origin_xyz_m=_vector(origin, "xyz", "0 0 0"),
            origin_rotation=rotation_from_rpy(_vector(origin, "rpy", "0 0 0")),
            axis=_vector(element.find("axis"), "xyz", "1 0 0"),
        )
        joints[joint.name] = joint
        children[joint.parent].append(joint.name)
    return RobotDescription(
        name=root.get("name", "robot"),
        links=links,
        joints=joints,
        children={name: tuple(names) for name, names in children.items()},
    )
