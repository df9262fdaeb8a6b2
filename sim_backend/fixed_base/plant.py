"""The emulated fixed-base robot's physics: MuJoCo with a flexible joint per actuated joint,
generated from the URDF text (the same text the controller's pinocchio model reads).

The tree is sim_backend/urdf_mjcf.py's (rotor hinge "<J>_motor" with the reflected inertia and
gearbox friction, gear hinge "<J>" with K and D, so link angle = motor + deflection); the root
link is welded to the world (a URDF link named "world" is MuJoCo's world body itself). Every
movable joint that is not flexible is welded at its locked angle. The tool: a sphere geom
"tool" and a site "tool" at the tool point of its link, where pushes act; a block, a box fixed
in the world, is the only other geom that collides (the links' own meshes are not part of the
description). Gravity -g along world z.

Sign conventions as the humanoid's (sim_backend/humanoid/plant.py): every joint angle in its
URDF axis convention; the gear torque tau_j = K (theta_m - theta_j) + D (dtheta_m - dtheta_j)
of (1) is what the spring carries.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import mujoco
import numpy as np

from sim_backend.fixed_base.params import FixedBaseTruthParams, GearFigures
from sim_backend.flexible_robot import strided_view
from sim_backend.spec import BlockSpec
from sim_backend.urdf_description import RobotDescription, parse_urdf
from sim_backend.urdf_mjcf import MOTOR_SUFFIX, BodyWriter, FlexibleJointFigures, num, vec

TOOL = "tool"  # the tool's geom and site
BLOCK = "block"  # the block's geom
WORLD_LINK = "world"  # a URDF's conventional name for the world it is fixed to


def build_mjcf(
    description: RobotDescription,
    joint_names: Sequence[str],
    gears: Sequence[GearFigures],
    velocity_gains_nms_per_rad: Sequence[float],
    truth: FixedBaseTruthParams,
    *,
    locked_angles_rad: Mapping[str, float] | None = None,
    tool: tuple[str, Sequence[float], float] | None = None,
    block: BlockSpec | None = None,
) -> str:
    """The MJCF text (module docstring). tool: (link, point in its frame [m], radius [m])."""
    locked = dict(locked_angles_rad or {})
    flexible = {
        name: FlexibleJointFigures(
            g.motor_reflected_inertia_kg_m2,
            g.gearbox_viscous_friction_nms_per_rad,
            g.gearbox_coulomb_friction_nm,
            g.gear_stiffness_nm_per_rad,
            g.gear_damping_nms_per_rad,
            kv,
        )
        for name, g, kv in zip(joint_names, gears, velocity_gains_nms_per_rad, strict=True)
    }
    missing = [name for name in joint_names if name not in description.joints]
    if missing:
        raise ValueError(f"the robot description has no joints {missing}")
    welded = {
        name: float(locked.get(name, 0.0))
        for name, joint in description.joints.items()
        if joint.kind in ("revolute", "continuous") and name not in flexible
    }
    extras: dict[str, list[str]] = {}
    if tool is not None:
        link, point, radius = tool
        if link not in description.links:
            raise ValueError(f"the robot description has no tool link {link!r}")
        extras[link] = [
            f'<geom name="{TOOL}" type="sphere" pos="{vec(point)}" size="{num(radius)}" '
            'mass="0" contype="1" conaffinity="1" condim="1"/>',
            f'<site name="{TOOL}" pos="{vec(point)}"/>',
        ]
    writer = BodyWriter(description, flexible, welded, links=truth.link_changes, link_extras=extras)
    root = description.root_link
    if root == WORLD_LINK:
        for joint_name in description.children.get(root, ()):
            writer.joint(2, description.joints[joint_name])
    else:
        writer.emit(2, f'<body name="{root}">')
        writer.link_contents(3, root)
        writer.emit(2, "</body>")
    block_xml = ""
    if block is not None:
        block_xml = (
            f'\n    <geom name="{BLOCK}" type="box" pos="{vec(block.centre_m)}" '
            f'size="{vec(np.asarray(block.size_m) / 2)}" contype="1" conaffinity="1" '
            f'condim="1" solref="{num(truth.block_time_constant_s)} '
            f'{num(truth.block_damping_ratio)}"/>'
        )
    body = "\n".join(writer.lines)
    actuators = "\n    ".join(writer.actuators)
    return f"""<mujoco model="{description.name}">
  <compiler angle="radian" inertiafromgeom="false" autolimits="true"/>
  <option timestep="{num(truth.physics_timestep_s)}" integrator="implicitfast"
          gravity="0 0 {num(-truth.gravity_m_s2)}"/>
  <default>
    <geom contype="0" conaffinity="0"/>
  </default>
  <worldbody>{block_xml}
{body}
  </worldbody>
  <actuator>
    {actuators}
  </actuator>
</mujoco>
"""


class FixedBasePlant:
    """MuJoCo model and state of the emulated fixed-base robot, joints in `joint_names`' order
    (the same per-joint face as the humanoid's plant, for `FlexibleJointRobot`)."""

    def __init__(
        self,
        urdf_text: str,
        joint_names: Sequence[str],
        gears: Sequence[GearFigures],
        velocity_gains_nms_per_rad: Sequence[float],
        truth: FixedBaseTruthParams | None = None,
        *,
        locked_angles_rad: Mapping[str, float] | None = None,
        tool: tuple[str, Sequence[float], float] | None = None,
        block: BlockSpec | None = None,
    ) -> None:
        self.truth = truth or FixedBaseTruthParams()
        self.joint_names = tuple(joint_names)
        self.description = parse_urdf(urdf_text)
        self.mjcf = build_mjcf(
            self.description,
            self.joint_names,
            gears,
            velocity_gains_nms_per_rad,
            self.truth,
            locked_angles_rad=locked_angles_rad,
            tool=tool,
            block=block,
        )
        model = mujoco.MjModel.from_xml_string(self.mjcf)
        self.model = model
        self.data = mujoco.MjData(model)
        motors = [model.joint(name + MOTOR_SUFFIX).id for name in self.joint_names]
        hinges = [model.joint(name).id for name in self.joint_names]
        self._motor_qpos = np.array([model.jnt_qposadr[j] for j in motors])
        self._motor_dof = np.array([model.jnt_dofadr[j] for j in motors])
        self._gear_qpos = np.array([model.jnt_qposadr[j] for j in hinges])
        self._gear_dof = np.array([model.jnt_dofadr[j] for j in hinges])
        self._actuator = np.array(
            [model.actuator(name + MOTOR_SUFFIX).id for name in self.joint_names]
        )
        self._stiffness = np.array([g.gear_stiffness_nm_per_rad for g in gears])
        self._damping = np.array([g.gear_damping_nms_per_rad for g in gears])
        self._tool_site = model.site(TOOL).id if tool is not None else -1
        self._tool_body = int(model.site_bodyid[self._tool_site]) if tool is not None else -1
        self._tool_geom = model.geom(TOOL).id if tool is not None else -1
        self._block_geom = model.geom(BLOCK).id if block is not None else -1
        self._contact_wrench = np.zeros(6)
        self._brake_damping = np.zeros(len(self.joint_names))
        self._braking = self._brake_applied = False
        self._tool_force = np.zeros(3)
        self._tool_force_applied = False
        self._motor_angle_view = strided_view(self.data.qpos, self._motor_qpos)
        self._motor_velocity_view = strided_view(self.data.qvel, self._motor_dof)
        mujoco.mj_forward(model, self.data)

    # --- state (joint order) ------------------------------------------------------------------
    @property
    def physics_timestep_s(self) -> float:
        return float(self.model.opt.timestep)

    @property
    def time_s(self) -> float:
        return float(self.data.time)

    @property
    def motor_angle_rad(self) -> np.ndarray:
        return self.data.qpos[self._motor_qpos].copy()

    @property
    def deflection_rad(self) -> np.ndarray:
        """Link angle minus motor angle (the gear hinge's coordinate)."""
        return self.data.qpos[self._gear_qpos].copy()

    @property
    def link_angle_rad(self) -> np.ndarray:
        """What link encoders measure: motor angle plus deflection."""
        return self.data.qpos[self._motor_qpos] + self.data.qpos[self._gear_qpos]

    @property
    def link_velocity_rad_s(self) -> np.ndarray:
        return self.data.qvel[self._motor_dof] + self.data.qvel[self._gear_dof]

    @property
    def motor_torque_nm(self) -> np.ndarray:
        """The servos' output torque this step (after their torque caps); a new array."""
        return self.data.actuator_force[self._actuator]

    @property
    def gear_torque_nm(self) -> np.ndarray:
        """(1): tau_j = K (theta_m - theta_j) + D (dtheta_m - dtheta_j), per joint [N m]."""
        return -(
            self._stiffness * self.data.qpos[self._gear_qpos]
            + self._damping * self.data.qvel[self._gear_dof]
        )

    def motor_state(self, joint: int) -> tuple[float, float]:
        return (
            float(self.data.qpos[self._motor_qpos[joint]]),
            float(self.data.qvel[self._motor_dof[joint]]),
        )

    def motor_state_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """(motor angles, motor velocities): views into MuJoCo's state where possible."""
        angles, velocities = self._motor_angle_view, self._motor_velocity_view
        if angles is None:
            angles = self.data.qpos[self._motor_qpos]
        if velocities is None:
            velocities = self.data.qvel[self._motor_dof]
        return angles, velocities

    def joint_motor_torque_nm(self, joint: int) -> float:
        return float(self.data.actuator_force[self._actuator[joint]])

    @property
    def tool_position_m(self) -> np.ndarray:
        """The tool point in the world [m] (after the last step)."""
        return self.data.site_xpos[self._tool_site].copy()

    def contact_force_n(self) -> float:
        """The normal force between the tool and the block (the block's force sensor)."""
        if self._block_geom < 0 or self._tool_geom < 0:
            return 0.0
        total = 0.0
        pair = {self._tool_geom, self._block_geom}
        for i in range(self.data.ncon):
            contact = self.data.contact[i]
            if {contact.geom1, contact.geom2} == pair:
                mujoco.mj_contactForce(self.model, self.data, i, self._contact_wrench)
                total += abs(self._contact_wrench[0])
        return total

    # --- inputs -------------------------------------------------------------------------------
    def set_servos(
        self, velocity_commands_rad_s: np.ndarray, torque_limits_nm: np.ndarray, kv: np.ndarray
    ) -> None:
        actuators = self._actuator
        self.model.actuator_forcerange[actuators, 0] = -torque_limits_nm
        self.model.actuator_forcerange[actuators, 1] = torque_limits_nm
        self.model.actuator_gainprm[actuators, 0] = kv
        self.model.actuator_biasprm[actuators, 2] = -kv
        self.data.ctrl[actuators] = velocity_commands_rad_s

    def set_velocity_commands(self, velocity_commands_rad_s: np.ndarray) -> None:
        self.data.ctrl[self._actuator] = velocity_commands_rad_s

    def set_brakes(self, brake_damping_nms_per_rad: np.ndarray) -> None:
        self._brake_damping[:] = brake_damping_nms_per_rad
        self._braking = bool(self._brake_damping.any())

    def set_tool_force(self, force_n: np.ndarray | Sequence[float]) -> None:
        """A push [N] (world frame) at the tool point until changed."""
        self._tool_force[:] = force_n

    def step(self) -> None:
        """Advance one physics step (a push at the tool is written while it acts, with its
        moment about the tool body's CoM, and zeroed once after)."""
        data = self.data
        if self._tool_force.any():
            body = self._tool_body
            arm = data.site_xpos[self._tool_site] - data.xipos[body]
            data.xfrc_applied[body, :3] = self._tool_force
            data.xfrc_applied[body, 3:] = np.cross(arm, self._tool_force)
            self._tool_force_applied = True
        elif self._tool_force_applied:
            data.xfrc_applied[self._tool_body, :] = 0.0
            self._tool_force_applied = False
        if self._braking or self._brake_applied:
            data.qfrc_applied[self._motor_dof] = -self._brake_damping * data.qvel[self._motor_dof]
            self._brake_applied = self._braking
        mujoco.mj_step(self.model, data)

    # --- set-up -------------------------------------------------------------------------------
    def place_at(self, link_angles_rad: Sequence[float] | np.ndarray) -> None:
        """At rest at these link angles with each gear already deflected by its static load,
        K deflection = -g(q) (the links do not drop at t = 0; the testbed's settle_statically)."""
        angles = np.asarray(link_angles_rad, dtype=float)
        if angles.shape != (len(self.joint_names),) or not np.all(np.isfinite(angles)):
            raise ValueError(f"link_angles_rad must be {len(self.joint_names)} finite angles")
        model, data = self.model, self.data
        mujoco.mj_resetData(model, data)
        data.qpos[self._motor_qpos] = angles
        data.qpos[self._gear_qpos] = 0.0
        mujoco.mj_forward(model, data)
        deflection = -data.qfrc_bias[self._gear_dof] / self._stiffness
        data.qpos[self._gear_qpos] = deflection
        data.qpos[self._motor_qpos] = angles - deflection
        mujoco.mj_forward(model, data)
