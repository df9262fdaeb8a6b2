"""MJCF of the emulated humanoid, generated from the URDF text (the same text the controller's
pinocchio model reads, so the two models share every figure).

Tree: the URDF's floating joint becomes MuJoCo's free joint on the pelvis. Each of the 12 leg
joints becomes a flexible joint, the way the 1-DoF testbed is built (sim_backend/plant.py):

    parent --[hinge "<J>_motor": rotor; armature = reflected inertia, gearbox friction]--> rotor
    rotor  --[hinge "<J>": the gear; stiffness K, damping D, springref 0]--> the URDF child link

so qpos("<J>") is the gear deflection and the link angle the external encoder sees is
qpos("<J>_motor") + qpos("<J>"). The rotor body carries 0.1 g (MuJoCo needs a moving body to
have mass; 1.2 g on a 50 kg robot). Every other revolute joint (waist, arms) is welded at the
posture `RobotTruthParams.upper_body_angles_rad`; fixed joints are welded.

Each motor hinge has a `general` actuator with force kv (ctrl - qvel): the servo's velocity-loop
P term, integrated implicitly by `implicitfast` (as in the testbed); its force range is the
firmware's torque cap, set every step. `rigid=True` builds the plain rigid robot instead (leg
joints are single hinges named "<J>", no actuators), for comparisons with the controller's model.

The feet: every box collision of the URDF (the soles under the *_AnkleRoll_Link) goes into a
massless body "<link>_ft" welded to the link at the link's origin (the ankle axis, where the
lab's MuJoCo model puts its foot F/T sensor site), with a site "<link>_ft" and MuJoCo `force`
and `torque` sensors on it: they read the wrench between that body and the foot link, i.e.
the ground's wrench on the robot carried to the ankle (the massless body has no weight of its
own to add). The floor is the plane z = 0, with any `floor_boxes` (objects to step on: rigid,
fixed to the world, the floor's contact figures); only soles, floor and boxes collide.
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np

from sim_backend.humanoid.description import Joint, Link, RobotDescription
from sim_backend.humanoid.params import LEG_JOINT_NAMES, RobotTruthParams
from sim_backend.spec import FloorBox

ROTOR_MASS_KG = 1e-4
ROTOR_INERTIA_KG_M2 = 1e-9
MOTOR_SUFFIX = "_motor"
ROTOR_SUFFIX = "_rotor"
FT_SUFFIX = "_ft"
FLOOR_BOX_PREFIX = "floor_box_"


def _num(value: float) -> str:
    return format(float(value), ".17g")


def _vec(values: Sequence[float] | np.ndarray) -> str:
    return " ".join(_num(v) for v in values)


def _quat(rotation: np.ndarray) -> str:
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(rotation, dtype=float).ravel())
    return _vec(quat)


def _axis_rotation(axis: np.ndarray, angle_rad: float) -> np.ndarray:
    axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle_rad) * k + (1 - np.cos(angle_rad)) * k @ k


class _Writer:
    def __init__(
        self,
        description: RobotDescription,
        params: RobotTruthParams,
        rigid: bool,
        velocity_gains_nms_per_rad: Sequence[float],
    ) -> None:
        self.d = description
        self.p = params
        self.rigid = rigid
        self.kv = list(velocity_gains_nms_per_rad)
        self.lines: list[str] = []
        self.actuators: list[str] = []
        self.sensors: list[str] = []
        self.ft_sites: list[str] = []

    def emit(self, depth: int, text: str) -> None:
        self.lines.append("  " * depth + text)

    def inertial(self, depth: int, link: Link) -> None:
        if link.inertial is None:
            return
        p = self.p
        inertial = link.inertial
        com = np.array(inertial.com_m, dtype=float)
        if link.name == p.com_offset_link:
            com = com + np.asarray(p.com_offset_m, dtype=float)
        tensor = inertial.inertia_kg_m2 * p.mass_scale
        full = (tensor[0, 0], tensor[1, 1], tensor[2, 2], tensor[0, 1], tensor[0, 2], tensor[1, 2])
        self.emit(
            depth,
            f'<inertial pos="{_vec(com)}" mass="{_num(inertial.mass_kg * p.mass_scale)}" '
            f'fullinertia="{_vec(full)}"/>',
        )

    def feet(self, depth: int, link: Link) -> None:
        if not link.boxes:
            return
        name = link.name + FT_SUFFIX
        c = self.p.contact
        self.emit(depth, f'<body name="{name}">')
        for box in link.boxes:
            self.emit(
                depth + 1,
                f'<geom name="{box.name}" type="box" pos="{_vec(box.centre_m)}" '
                f'size="{_vec(np.asarray(box.size_m) / 2)}" contype="1" conaffinity="1" '
                f'condim="3" friction="{_num(c.friction)} 0.005 0.0001" '
                f'solref="{_num(c.time_constant_s)} {_num(c.damping_ratio)}"/>',
            )
        self.emit(depth + 1, f'<site name="{name}" pos="0 0 0"/>')
        self.emit(depth, "</body>")
        self.ft_sites.append(name)
        self.sensors.append(f'<force name="{name}_force" site="{name}"/>')
        self.sensors.append(f'<torque name="{name}_torque" site="{name}"/>')

    def link_contents(self, depth: int, link_name: str) -> None:
        link = self.d.links[link_name]
        self.inertial(depth, link)
        self.feet(depth, link)
        for joint_name in self.d.children.get(link_name, ()):
            self.joint(depth, self.d.joints[joint_name])

    def joint(self, depth: int, joint: Joint) -> None:
        pos = _vec(joint.origin_xyz_m)
        if joint.kind == "floating":
            raise ValueError(f"floating joint {joint.name!r} below the root is not supported")
        if joint.kind in ("revolute", "continuous") and joint.name in LEG_JOINT_NAMES:
            self.leg_joint(depth, joint)
            return
        rotation = joint.origin_rotation
        if joint.kind in ("revolute", "continuous"):
            angles = self.p.upper_body_angles_rad
            if joint.name not in angles:
                raise ValueError(f"no weld angle for the joint {joint.name!r}")
            rotation = rotation @ _axis_rotation(joint.axis, angles[joint.name])
        elif joint.kind != "fixed":
            raise ValueError(f"joint {joint.name!r}: type {joint.kind!r} is not supported")
        self.emit(depth, f'<body name="{joint.child}" pos="{pos}" quat="{_quat(rotation)}">')
        self.link_contents(depth + 1, joint.child)
        self.emit(depth, "</body>")

    def leg_joint(self, depth: int, joint: Joint) -> None:
        index = LEG_JOINT_NAMES.index(joint.name)
        p = self.p
        axis = _vec(joint.axis)
        placement = f'pos="{_vec(joint.origin_xyz_m)}" quat="{_quat(joint.origin_rotation)}"'
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
            f'armature="{_num(p.per_joint("motor_reflected_inertia_kg_m2")[index])}" '
            f'damping="{_num(p.per_joint("gearbox_viscous_friction_nms_per_rad")[index])}" '
            f'frictionloss="{_num(p.per_joint("gearbox_coulomb_friction_nm")[index])}"/>',
        )
        self.emit(
            depth + 1,
            f'<inertial pos="0 0 0" mass="{_num(ROTOR_MASS_KG)}" '
            f'diaginertia="{_vec([ROTOR_INERTIA_KG_M2] * 3)}"/>',
        )
        self.emit(depth + 1, f'<body name="{joint.child}">')
        self.emit(
            depth + 2,
            f'<joint name="{joint.name}" type="hinge" axis="{axis}" springref="0" '
            f'stiffness="{_num(p.per_joint("gear_stiffness_nm_per_rad")[index])}" '
            f'damping="{_num(p.per_joint("gear_damping_nms_per_rad")[index])}"/>',
        )
        self.link_contents(depth + 2, joint.child)
        self.emit(depth + 1, "</body>")
        self.emit(depth, "</body>")
        kv = self.kv[index]
        self.actuators.append(
            f'<general name="{motor}" joint="{motor}" gainprm="{_num(kv)}" biastype="affine" '
            f'biasprm="0 0 {_num(-kv)}" ctrllimited="false" forcelimited="true" '
            f'forcerange="-1000 1000"/>'
        )


def build_mjcf(
    description: RobotDescription,
    params: RobotTruthParams,
    *,
    rigid: bool = False,
    velocity_gains_nms_per_rad: Sequence[float] | None = None,
    floor_boxes: Sequence[FloorBox] = (),
) -> str:
    """The MJCF text (see the module docstring). velocity_gains: the servos' kv per leg joint
    (default: each joint's H54ServoParams.velocity_gain_nms_per_rad); floor_boxes: objects on
    the floor, geoms "floor_box_<i>"."""
    if velocity_gains_nms_per_rad is None:
        velocity_gains_nms_per_rad = [
            params.servo_params(i).velocity_gain_nms_per_rad for i in range(len(LEG_JOINT_NAMES))
        ]
    root = description.root_link
    floating = [
        description.joints[name]
        for name in description.children.get(root, ())
        if description.joints[name].kind == "floating"
    ]
    if len(floating) != 1:
        raise ValueError("the robot description must hang from one floating joint at its root")
    base = floating[0]
    missing = [name for name in LEG_JOINT_NAMES if name not in description.joints]
    if missing:
        raise ValueError(f"the robot description lacks the leg joints {missing}")
    writer = _Writer(description, params, rigid, velocity_gains_nms_per_rad)
    writer.emit(2, f'<body name="{base.child}" pos="{_vec(base.origin_xyz_m)}">')
    writer.emit(3, f'<freejoint name="{base.name}"/>')
    writer.link_contents(3, base.child)
    writer.emit(2, "</body>")
    body = "\n".join(writer.lines)
    actuators = "\n    ".join(writer.actuators)
    sensors = "\n    ".join(writer.sensors)
    c = params.contact
    contact = (
        f'contype="1" conaffinity="1" condim="3" friction="{_num(c.friction)} 0.005 0.0001" '
        f'solref="{_num(c.time_constant_s)} {_num(c.damping_ratio)}"'
    )
    boxes = "".join(
        f'\n    <geom name="{FLOOR_BOX_PREFIX}{i}" type="box" '
        f'pos="{_vec((*box.centre_m, box.height_m / 2))}" '
        f'size="{_vec(np.asarray(box.size_m) / 2)}" {contact}/>'
        for i, box in enumerate(floor_boxes)
    )
    return f"""<mujoco model="{description.name}">
  <compiler angle="radian" inertiafromgeom="false" autolimits="true"/>
  <option timestep="{_num(params.physics_timestep_s)}" integrator="implicitfast"
          gravity="0 0 {_num(-params.gravity_m_s2)}" cone="{c.friction_cone}"
          impratio="{_num(c.friction_impedance_ratio)}"/>
  <default>
    <geom contype="0" conaffinity="0"/>
  </default>
  <worldbody>
    <geom name="floor" type="plane" size="0 0 0.05" contype="1" conaffinity="1" condim="3"
          friction="{_num(c.friction)} 0.005 0.0001"
          solref="{_num(c.time_constant_s)} {_num(c.damping_ratio)}"/>{boxes}
{body}
  </worldbody>
  <actuator>
    {actuators}
  </actuator>
  <sensor>
    {sensors}
  </sensor>
</mujoco>
"""
