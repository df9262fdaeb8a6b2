"""MJCF bodies generated from a URDF robot description, with flexible joints where the robot has
actuators: the tree both the humanoid (sim_backend/humanoid/mjcf.py) and a fixed-base robot
(sim_backend/fixed_base/mjcf.py) are built from, each adding its own world around it.

Each flexible joint J becomes two hinges, the way the 1-DoF testbed is built
(sim_backend/plant.py):

    parent --[hinge "<J>_motor": rotor; armature = reflected inertia, gearbox friction]--> rotor
    rotor  --[hinge "<J>": the gear; stiffness K, damping D, springref 0]--> the URDF child link

so qpos("<J>") is the gear deflection and the link angle an external encoder sees is
qpos("<J>_motor") + qpos("<J>"). The rotor body carries 0.1 g (MuJoCo needs a moving body to
have mass). Every other revolute joint is welded at its angle in `welded_angles_rad`; fixed
joints are welded. Each motor hinge has a `general` actuator with force kv (ctrl - qvel): the
servo's velocity-loop P term, integrated implicitly by `implicitfast`; its force range is the
firmware's torque cap, set every step. `rigid=True` builds the plain rigid robot instead (the
flexible joints are single hinges named "<J>", no actuators).

Box collisions (the humanoid's soles) go into a massless body "<link>_ft" welded to the link at
the link's origin, with a site "<link>_ft" and MuJoCo `force` and `torque` sensors on it: they
read the wrench between that body and the link (the massless body adds no weight of its own).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from sim_backend.urdf_description import Joint, Link, RobotDescription

ROTOR_MASS_KG = 1e-4
ROTOR_INERTIA_KG_M2 = 1e-9
MOTOR_SUFFIX = "_motor"
ROTOR_SUFFIX = "_rotor"
FT_SUFFIX = "_ft"


def num(value: float) -> str:
    return format(float(value), ".17g")


def vec(values: Sequence[float] | np.ndarray) -> str:
    return " ".join(num(v) for v in values)


def quat(rotation: np.ndarray) -> str:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(rotation, dtype=float).ravel())
    return vec(q)


def axis_rotation(axis: np.ndarray, angle_rad: float) -> np.ndarray:
    axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle_rad) * k + (1 - np.cos(angle_rad)) * k @ k


@dataclass(frozen=True)
class FlexibleJointFigures:
    """One flexible joint of the generated model: its rotor, its gear and its servo's kv."""

    reflected_inertia_kg_m2: float
    gearbox_viscous_friction_nms_per_rad: float
    gearbox_coulomb_friction_nm: float
    gear_stiffness_nm_per_rad: float
    gear_damping_nms_per_rad: float
    velocity_gain_nms_per_rad: float


@dataclass(frozen=True)
class LinkChanges:
    """What the emulated truth changes of the URDF's links: every mass and inertia scaled, and
    one link's centre of mass shifted (a payload the controller does not know of)."""

    mass_scale: float = 1.0
    com_offset_link: str = ""
    com_offset_m: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class SoleContact:
    """The box collisions' contact: friction and MuJoCo's solref (time constant, damping)."""

    friction: float
    time_constant_s: float
    damping_ratio: float


class BodyWriter:
    """The MJCF body tree of a URDF description (see the module docstring): `link_contents`
    writes a link's inertial, boxes, `link_extras` (MJCF lines a robot adds inside a link's
    body: a tool's geom and site) and child joints; `lines`, `actuators`, `sensors` and
    `ft_sites` collect what the tree adds to the document."""

    def __init__(
        self,
        description: RobotDescription,
        flexible: Mapping[str, FlexibleJointFigures],
        welded_angles_rad: Mapping[str, float],
        *,
        links: LinkChanges = LinkChanges(),
        sole_contact: SoleContact | None = None,
        link_extras: Mapping[str, Sequence[str]] | None = None,
        rigid: bool = False,
    ) -> None:
        self.d = description
        self.link_extras = link_extras or {}
        self.flexible = flexible
        self.welded = welded_angles_rad
        self.links = links
        self.sole_contact = sole_contact
        self.rigid = rigid
        self.lines: list[str] = []
        self.actuators: list[str] = []
        self.sensors: list[str] = []
        self.ft_sites: list[str] = []

    def emit(self, depth: int, text: str) -> None:
        self.lines.append("  " * depth + text)

    def inertial(self, depth: int, link: Link) -> None:
        if link.inertial is None:
            return
        changes = self.links
        inertial = link.inertial
        com = np.array(inertial.com_m, dtype=float)
        if link.name == changes.com_offset_link:
            com = com + np.asarray(changes.com_offset_m, dtype=float)
        tensor = inertial.inertia_kg_m2 * changes.mass_scale
        full = (tensor[0, 0], tensor[1, 1], tensor[2, 2], tensor[0, 1], tensor[0, 2], tensor[1, 2])
        self.emit(
            depth,
            f'<inertial pos="{vec(com)}" mass="{num(inertial.mass_kg * changes.mass_scale)}" '
            f'fullinertia="{vec(full)}"/>',
        )

    def boxes(self, depth: int, link: Link) -> None:
        if not link.boxes or self.sole_contact is None:
            return
        name = link.name + FT_SUFFIX
        c = self.sole_contact
        self.emit(depth, f'<body name="{name}">')
        for box in link.boxes:
            self.emit(
                depth + 1,
                f'<geom name="{box.name}" type="box" pos="{vec(box.centre_m)}" '
                f'size="{vec(np.asarray(box.size_m) / 2)}" contype="1" conaffinity="1" '
                f'condim="3" friction="{num(c.friction)} 0.005 0.0001" '
                f'solref="{num(c.time_constant_s)} {num(c.damping_ratio)}"/>',
            )
        self.emit(depth + 1, f'<site name="{name}" pos="0 0 0"/>')
        self.emit(depth, "</body>")
        self.ft_sites.append(name)
        self.sensors.append(f'<force name="{name}_force" site="{name}"/>')
        self.sensors.append(f'<torque name="{name}_torque" site="{name}"/>')

    def link_contents(self, depth: int, link_name: str) -> None:
        link = self.d.links[link_name]
        self.inertial(depth, link)
        self.boxes(depth, link)
        for line in self.link_extras.get(link_name, ()):
            self.emit(depth, line)
        for joint_name in self.d.children.get(link_name, ()):
            self.joint(depth, self.d.joints[joint_name])

    def joint(self, depth: int, joint: Joint) -> None:
        pos = vec(joint.origin_xyz_m)
        if joint.kind == "floating":
            raise ValueError(f"floating joint {joint.name!r} below the root is not supported")
        if joint.kind in ("revolute", "continuous") and joint.name in self.flexible:
            self.flexible_joint(depth, joint)
            return
        rotation = joint.origin_rotation
        if joint.kind in ("revolute", "continuous"):
            if joint.name not in self.welded:
                raise ValueError(f"no weld angle for the joint {joint.name!r}")
            rotation = rotation @ axis_rotation(joint.axis, self.welded[joint.name])
        elif joint.kind != "fixed":
            raise ValueError(f"joint {joint.name!r}: type {joint.kind!r} is not supported")
        self.emit(depth, f'<body name="{joint.child}" pos="{pos}" quat="{quat(rotation)}">')
        self.link_contents(depth + 1, joint.child)
        self.emit(depth, "</body>")

    def flexible_joint(self, depth: int, joint: Joint) -> None:
        f = self.flexible[joint.name]
        axis = vec(joint.axis)
        placement = f'pos="{vec(joint.origin_xyz_m)}" quat="{quat(joint.origin_rotation)}"'
        if self.rigid:
            self.emit(depth, f'<body name="{joint.child}" {placement}>')
            self.emit(depth + 1, f'<joint name="{joint.name}" type="hinge" axis="{axis}"/>')
            self.link_contents(depth + 1, joint.child)
            self.emit(depth, "</body>")
            return
        motor = joint.name + MOTOR_SUFFIX
        self.emit(depth, f'<body name="{joint.name}{ROTOR_SUFFIX}" {placement}>')
        self.emit(
            depth + 1,
            f'<joint name="{motor}" type="hinge" axis="{axis}" '
            f'armature="{num(f.reflected_inertia_kg_m2)}" '
            f'damping="{num(f.gearbox_viscous_friction_nms_per_rad)}" '
            f'frictionloss="{num(f.gearbox_coulomb_friction_nm)}"/>',
        )
        self.emit(
            depth + 1,
            f'<inertial pos="0 0 0" mass="{num(ROTOR_MASS_KG)}" '
            f'diaginertia="{vec([ROTOR_INERTIA_KG_M2] * 3)}"/>',
        )
        self.emit(depth + 1, f'<body name="{joint.child}">')
        self.emit(
            depth + 2,
            f'<joint name="{joint.name}" type="hinge" axis="{axis}" springref="0" '
            f'stiffness="{num(f.gear_stiffness_nm_per_rad)}" '
            f'damping="{num(f.gear_damping_nms_per_rad)}"/>',
        )
        self.link_contents(depth + 2, joint.child)
        self.emit(depth + 1, "</body>")
        self.emit(depth, "</body>")
        kv = f.velocity_gain_nms_per_rad
        self.actuators.append(
            f'<general name="{motor}" joint="{motor}" gainprm="{num(kv)}" biastype="affine" '
            f'biasprm="0 0 {num(-kv)}" ctrllimited="false" forcelimited="true" '
            f'forcerange="-1000 1000"/>'
        )
