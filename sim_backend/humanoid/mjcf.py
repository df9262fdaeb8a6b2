"""MJCF of the emulated humanoid, generated from the URDF text (the same text the controller's
pinocchio model reads, so the two models share every figure).

Tree (sim_backend/urdf_mjcf.py, shared with the fixed-base robots): the URDF's floating joint
becomes MuJoCo's free joint on the pelvis, or, `suspended=True`, nothing: the pelvis is fixed in
the world at SUSPENSION_HEIGHT_M, upright, the robot hung from a gantry with its legs free (for
identifying them). Each of the 12 leg joints becomes a flexible joint, the way the 1-DoF
testbed is built (sim_backend/plant.py):

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

import numpy as np

from sim_backend.humanoid.params import LEG_JOINT_NAMES, RobotTruthParams
from sim_backend.spec import FloorBox
from sim_backend.urdf_description import RobotDescription
from sim_backend.urdf_mjcf import (
    FT_SUFFIX,
    MOTOR_SUFFIX,
    ROTOR_MASS_KG,
    BodyWriter,
    FlexibleJointFigures,
    LinkChanges,
    SoleContact,
)
from sim_backend.urdf_mjcf import num as _num
from sim_backend.urdf_mjcf import vec as _vec

__all__ = [
    "FT_SUFFIX",
    "MOTOR_SUFFIX",
    "ROTOR_MASS_KG",
    "SUSPENSION_HEIGHT_M",
    "build_mjcf",
    "leg_figures",
]

FLOOR_BOX_PREFIX = "floor_box_"

# Where a suspended robot's pelvis (base_link's origin) hangs above the floor [m]. Standing on
# straight legs DYROS-JET's pelvis origin is 0.924 m above its soles' undersides (the URDF's
# figures: HumanoidPlant.place_standing at zero leg angles), so 1.2 m leaves both soles 0.28 m
# clear with the legs straight (more with the knees bent; a sole tipped 60 deg at the ankle
# still clears ~0.15 m): the floor stays in the model and nothing touches it.
SUSPENSION_HEIGHT_M = 1.2


def leg_figures(
    params: RobotTruthParams, velocity_gains_nms_per_rad: Sequence[float]
) -> dict[str, FlexibleJointFigures]:
    """Each leg joint's rotor, gear and kv from the robot's truth."""
    p = params
    return {
        name: FlexibleJointFigures(
            p.per_joint("motor_reflected_inertia_kg_m2")[i],
            p.per_joint("gearbox_viscous_friction_nms_per_rad")[i],
            p.per_joint("gearbox_coulomb_friction_nm")[i],
            p.per_joint("gear_stiffness_nm_per_rad")[i],
            p.per_joint("gear_damping_nms_per_rad")[i],
            velocity_gains_nms_per_rad[i],
        )
        for i, name in enumerate(LEG_JOINT_NAMES)
    }


def build_mjcf(
    description: RobotDescription,
    params: RobotTruthParams,
    *,
    rigid: bool = False,
    velocity_gains_nms_per_rad: Sequence[float] | None = None,
    floor_boxes: Sequence[FloorBox] = (),
    suspended: bool = False,
) -> str:
    """The MJCF text (see the module docstring). velocity_gains: the servos' kv per leg joint
    (default: each joint's H54ServoParams.velocity_gain_nms_per_rad); floor_boxes: objects on
    the floor, geoms "floor_box_<i>"; suspended: the pelvis fixed SUSPENSION_HEIGHT_M above the
    floor, no free joint (so qpos holds the leg hinges alone, from address 0)."""
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
    c = params.contact
    writer = BodyWriter(
        description,
        leg_figures(params, velocity_gains_nms_per_rad),
        params.upper_body_angles_rad,
        links=LinkChanges(params.mass_scale, params.com_offset_link, params.com_offset_m),
        sole_contact=SoleContact(c.friction, c.time_constant_s, c.damping_ratio),
        rigid=rigid,
    )
    if suspended:  # hung from the gantry: welded to the world
        hung = np.asarray(base.origin_xyz_m, dtype=float) + (0.0, 0.0, SUSPENSION_HEIGHT_M)
        writer.emit(2, f'<body name="{base.child}" pos="{_vec(hung)}">')
    else:
        writer.emit(2, f'<body name="{base.child}" pos="{_vec(base.origin_xyz_m)}">')
        writer.emit(3, f'<freejoint name="{base.name}"/>')
    writer.link_contents(3, base.child)
    writer.emit(2, "</body>")
    body = "\n".join(writer.lines)
    actuators = "\n    ".join(writer.actuators)
    sensors = "\n    ".join(writer.sensors)
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
