"""The emulated DYROS-JET's physics: MuJoCo with 12 flexible leg joints (see mjcf.py).

A per-joint API like the testbed's `TestbedPlant`, for 12 joints in the lab's leg order, plus
what a humanoid adds: the feet's force/torque sensors, the pelvis pose, the centre of mass and
a push on the pelvis. It knows nothing of buses or firmware (robot.py puts the H54 firmware in
front of it).

Sign conventions: every joint angle in its URDF axis convention; link angle = motor angle +
gear deflection; the gear torque tau_j = K (theta_m - theta_j) + D (dtheta_m - dtheta_j) of the
paper's (1) is what the spring carries (MuJoCo's passive force on the deflection coordinate is
-tau_j). A foot wrench is the ground's force and moment ON THE ROBOT, in the foot sensor's frame
(the *_AnkleRoll_Link frame, at the ankle axis), the moment about the sensor's origin: standing
still, the vertical forces are positive and sum to the robot's weight.

Suspended (`suspended=True`): the pelvis is fixed in the world (no free joint; mjcf.py), the legs
hang free of the floor, `hang` places them; the feet's sensors then read ~0 and a push on the
pelvis goes into the gantry.

Gearbox friction: a joint whose law varies (RobotTruthParams.gearbox_friction_model other than
"coulomb-viscous") has its bound rewritten into `dof_frictionloss` at its motor dof before every
step, from its motor speed and its gear torque at the step's start, as the testbed does
(sim_backend/plant.py, sim_backend/friction.py); the others keep the MJCF's constant bound.
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np

from sim_backend.flexible_robot import strided_view
from sim_backend.friction import GearboxFriction, GearboxFrictionParams
from sim_backend.humanoid.mjcf import FT_SUFFIX, MOTOR_SUFFIX, build_mjcf
from sim_backend.humanoid.params import (
    FOOT_LINK_NAMES,
    LEG_JOINT_NAMES,
    N_LEG_JOINTS,
    PELVIS_LINK_NAME,
    RobotTruthParams,
)
from sim_backend.spec import FloorBox
from sim_backend.urdf_description import parse_urdf


class HumanoidPlant:
    """MuJoCo model and state of the emulated robot; see the module docstring."""

    def __init__(
        self,
        urdf_text: str,
        params: RobotTruthParams | None = None,
        *,
        velocity_gains_nms_per_rad: Sequence[float] | None = None,
        floor_boxes: Sequence[FloorBox] = (),
        suspended: bool = False,
    ) -> None:
        self.params = params or RobotTruthParams()
        self.description = parse_urdf(urdf_text)
        self.floor_boxes = tuple(floor_boxes)
        self.suspended = suspended
        self.mjcf = build_mjcf(
            self.description,
            self.params,
            velocity_gains_nms_per_rad=velocity_gains_nms_per_rad,
            floor_boxes=self.floor_boxes,
            suspended=suspended,
        )
        model = mujoco.MjModel.from_xml_string(self.mjcf)
        self.model = model
        self.data = mujoco.MjData(model)

        def joint_id(name: str) -> int:
            return model.joint(name).id

        motors = [joint_id(name + MOTOR_SUFFIX) for name in LEG_JOINT_NAMES]
        gears = [joint_id(name) for name in LEG_JOINT_NAMES]
        self._motor_qpos = np.array([model.jnt_qposadr[j] for j in motors])
        self._motor_dof = np.array([model.jnt_dofadr[j] for j in motors])
        self._gear_qpos = np.array([model.jnt_qposadr[j] for j in gears])
        self._gear_dof = np.array([model.jnt_dofadr[j] for j in gears])
        self._actuator = np.array(
            [model.actuator(name + MOTOR_SUFFIX).id for name in LEG_JOINT_NAMES]
        )
        self._stiffness = np.array(self.params.per_joint("gear_stiffness_nm_per_rad"))
        self._damping = np.array(self.params.per_joint("gear_damping_nms_per_rad"))
        self._pelvis_body = model.body(PELVIS_LINK_NAME).id
        self._ft_body = [model.body(name + FT_SUFFIX).id for name in FOOT_LINK_NAMES]
        self._ft_site = [model.site(name + FT_SUFFIX).id for name in FOOT_LINK_NAMES]
        self._sole_geoms = [
            [g for g in range(model.ngeom) if model.geom_bodyid[g] == body]
            for body in self._ft_body
        ]
        self._force_adr = [
            model.sensor_adr[model.sensor(name + FT_SUFFIX + "_force").id]
            for name in FOOT_LINK_NAMES
        ]
        self._torque_adr = [
            model.sensor_adr[model.sensor(name + FT_SUFFIX + "_torque").id]
            for name in FOOT_LINK_NAMES
        ]
        self._brake_damping = np.zeros(N_LEG_JOINTS)
        self._braking = self._brake_applied = False
        self._pelvis_force = np.zeros(3)
        self._pelvis_force_due = True  # xfrc_applied to be written before the next step
        # The motors' angles and velocities as views into MuJoCo's state where the hinges'
        # addresses are evenly spaced (they are: motor and gear hinges alternate), so that the
        # firmware reads them every step without a copy; copies otherwise.
        self._motor_angle_view = strided_view(self.data.qpos, self._motor_qpos)
        self._motor_velocity_view = strided_view(self.data.qvel, self._motor_dof)
        # the joints whose gearbox friction law varies: their bounds rewritten before each step
        laws = [self.params.gearbox_friction(i) for i in range(N_LEG_JOINTS)]
        varying = np.array([i for i, law in enumerate(laws) if law.varies], dtype=int)
        self._friction = (
            _VaryingFriction(
                [laws[i] for i in varying],
                self._motor_dof[varying],
                self._gear_qpos[varying],
                self._gear_dof[varying],
                self._stiffness[varying],
                self._damping[varying],
            )
            if varying.size
            else None
        )
        mujoco.mj_forward(model, self.data)

    # --- state (copies, lab leg order) --------------------------------------------------------
    @property
    def motor_dof_indices(self) -> np.ndarray:
        """MuJoCo's dof index of each joint's motor hinge (lab order)."""
        return self._motor_dof.copy()

    @property
    def gear_dof_indices(self) -> np.ndarray:
        """MuJoCo's dof index of each joint's gear hinge (the deflection)."""
        return self._gear_dof.copy()

    @property
    def actuator_indices(self) -> np.ndarray:
        """MuJoCo's actuator index of each joint's servo."""
        return self._actuator.copy()

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
    def motor_velocity_rad_s(self) -> np.ndarray:
        return self.data.qvel[self._motor_dof].copy()

    @property
    def deflection_rad(self) -> np.ndarray:
        """Link angle minus motor angle (the gear hinge's coordinate)."""
        return self.data.qpos[self._gear_qpos].copy()

    @property
    def link_angle_rad(self) -> np.ndarray:
        """What the external link encoders measure: motor angle plus deflection."""
        return self.data.qpos[self._motor_qpos] + self.data.qpos[self._gear_qpos]

    @property
    def link_velocity_rad_s(self) -> np.ndarray:
        return self.data.qvel[self._motor_dof] + self.data.qvel[self._gear_dof]

    @property
    def motor_torque_nm(self) -> np.ndarray:
        """The servo's output torque this step (after its torque cap); a new array."""
        return self.data.actuator_force[self._actuator]

    @property
    def gear_torque_nm(self) -> np.ndarray:
        """(1): tau_j = K (theta_m - theta_j) + D (dtheta_m - dtheta_j), per joint [N m]."""
        return -(
            self._stiffness * self.data.qpos[self._gear_qpos]
            + self._damping * self.data.qvel[self._gear_dof]
        )

    def motor_state(self, joint: int) -> tuple[float, float]:
        """(motor angle, motor velocity) of one joint, for the firmware's per-step loop."""
        return (
            float(self.data.qpos[self._motor_qpos[joint]]),
            float(self.data.qvel[self._motor_dof[joint]]),
        )

    def motor_state_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """(motor angles, motor velocities) of the 12 joints, the firmware's input every step:
        views into MuJoCo's state where possible (they follow the next step: copy to keep)."""
        angles, velocities = self._motor_angle_view, self._motor_velocity_view
        if angles is None:
            angles = self.data.qpos[self._motor_qpos]
        if velocities is None:
            velocities = self.data.qvel[self._motor_dof]
        return angles, velocities

    def joint_link_angle_rad(self, joint: int) -> float:
        """One joint's link angle (the CAN encoder's source)."""
        return float(
            self.data.qpos[self._motor_qpos[joint]] + self.data.qpos[self._gear_qpos[joint]]
        )

    def joint_link_velocity_rad_s(self, joint: int) -> float:
        return float(self.data.qvel[self._motor_dof[joint]] + self.data.qvel[self._gear_dof[joint]])

    def joint_motor_torque_nm(self, joint: int) -> float:
        return float(self.data.actuator_force[self._actuator[joint]])

    # --- pelvis, CoM, feet --------------------------------------------------------------------
    @property
    def pelvis_position_m(self) -> np.ndarray:
        return self.data.xpos[self._pelvis_body].copy()

    @property
    def pelvis_rotation(self) -> np.ndarray:
        """world <- pelvis, 3 x 3."""
        return self.data.xmat[self._pelvis_body].reshape(3, 3).copy()

    @property
    def pelvis_quaternion_wxyz(self) -> tuple[float, float, float, float]:
        """world <- pelvis as MuJoCo's unit quaternion (w, x, y, z)."""
        w, x, y, z = (float(v) for v in self.data.xquat[self._pelvis_body])
        return w, x, y, z

    @property
    def pelvis_tilt_rad(self) -> float:
        """Angle between the pelvis z axis and the vertical (roll and pitch together)."""
        return float(np.arccos(np.clip(self.data.xmat[self._pelvis_body][8], -1.0, 1.0)))

    @property
    def centre_of_mass_m(self) -> np.ndarray:
        """The whole robot's CoM in the world [m] (MuJoCo's subtree CoM of the pelvis)."""
        return self.data.subtree_com[self._pelvis_body].copy()

    def foot_wrench(self, side: int) -> tuple[np.ndarray, np.ndarray]:
        """(force [N], moment [N m]) of the ground on the robot at foot `side` (0 left, 1 right),
        in the sensor frame, the moment about the sensor origin (module docstring).

        MuJoCo's force/torque sensors read what the foot link (parent) exerts on the massless
        sensor body; that body's balance makes the ground's wrench the opposite.
        """
        force = self.data.sensordata[self._force_adr[side] : self._force_adr[side] + 3]
        torque = self.data.sensordata[self._torque_adr[side] : self._torque_adr[side] + 3]
        return np.negative(force), np.negative(torque)

    def ft_sensor_pose(self, side: int) -> tuple[np.ndarray, np.ndarray]:
        """(position [m], rotation world <- sensor) of foot `side`'s force/torque sensor."""
        site = self._ft_site[side]
        return self.data.site_xpos[site].copy(), self.data.site_xmat[site].reshape(3, 3).copy()

    def sole_in_contact(self, side: int) -> bool:
        geoms = self._sole_geoms[side]
        return any(
            self.data.contact[i].geom1 in geoms or self.data.contact[i].geom2 in geoms
            for i in range(self.data.ncon)
        )

    def sole_contacts(self, side: int) -> list[tuple[str, np.ndarray]]:
        """Where sole `side` touches the world: (the other geom's name, the contact point [m])
        for each of MuJoCo's active contacts of that sole (e.g. "floor", "floor_box_0")."""
        geoms = self._sole_geoms[side]
        found = []
        for i in range(self.data.ncon):
            contact = self.data.contact[i]
            if contact.geom1 in geoms or contact.geom2 in geoms:
                other = contact.geom2 if contact.geom1 in geoms else contact.geom1
                found.append((self.model.geom(other).name, contact.pos.copy()))
        return found

    # --- inputs -------------------------------------------------------------------------------
    def set_servos(
        self, velocity_commands_rad_s: np.ndarray, torque_limits_nm: np.ndarray, kv: np.ndarray
    ) -> None:
        """The servos' velocity-loop inputs and torque caps for this step, with the velocity P
        gains kv (implicit actuator force kv (ctrl - qvel)); arrays in the lab order."""
        actuators = self._actuator
        self.model.actuator_forcerange[actuators, 0] = -torque_limits_nm
        self.model.actuator_forcerange[actuators, 1] = torque_limits_nm
        self.model.actuator_gainprm[actuators, 0] = kv
        self.model.actuator_biasprm[actuators, 2] = -kv
        self.data.ctrl[actuators] = velocity_commands_rad_s

    def set_velocity_commands(self, velocity_commands_rad_s: np.ndarray) -> None:
        """The servos' velocity-loop inputs alone (torque caps and gains as last set)."""
        self.data.ctrl[self._actuator] = velocity_commands_rad_s

    def set_brakes(self, brake_damping_nms_per_rad: np.ndarray) -> None:
        """The dynamic brakes' motor-side damping per joint (shorted windings while torque is
        off; 0 while the servo drives the motor)."""
        self._brake_damping[:] = brake_damping_nms_per_rad
        self._braking = bool(self._brake_damping.any())

    def set_pelvis_force(self, force_n: np.ndarray | Sequence[float]) -> None:
        """A push [N] (world frame) applied at the pelvis's centre of mass until changed."""
        self._pelvis_force[:] = force_n
        self._pelvis_force_due = True

    def step(self) -> None:
        """Advance one physics step."""
        data = self.data
        if self._pelvis_force_due:  # (MuJoCo leaves xfrc_applied as it was written)
            data.xfrc_applied[self._pelvis_body, :3] = self._pelvis_force
            self._pelvis_force_due = False
        if self._braking or self._brake_applied:  # (no brake: nothing to apply, nothing to undo)
            data.qfrc_applied[self._motor_dof] = -self._brake_damping * data.qvel[self._motor_dof]
            self._brake_applied = self._braking
        if self._friction is not None:  # (coulomb-viscous everywhere: the MJCF's constant)
            self._friction.write(self.model, data)
        mujoco.mj_step(self.model, data)

    # --- set-up -------------------------------------------------------------------------------
    def place_standing(
        self,
        leg_angles_rad: np.ndarray | Sequence[float],
        support_feet: Sequence[int] = (0, 1),
    ) -> None:
        """Put the robot at rest at these link angles (no deflection: motors = links) with the
        support sole(s) flat on the floor (double support: the pelvis orientation halfway
        between the two soles' flat orientations) and their centres around x = y = 0.

        The gears are not yet loaded: let the robot settle (step) before measuring statics.
        """
        if self.suspended:
            raise ValueError("a suspended robot does not stand: hang it (HumanoidPlant.hang)")
        angles = _leg_angles(leg_angles_rad)
        if not support_feet or any(side not in (0, 1) for side in support_feet):
            raise ValueError("support_feet must name feet 0 (left) and/or 1 (right)")
        model, data = self.model, self.data
        mujoco.mj_resetData(model, data)
        self._pelvis_force_due = True  # (the reset cleared xfrc_applied)
        data.qpos[self._motor_qpos] = angles
        data.qpos[self._gear_qpos] = 0.0
        data.qpos[:7] = (0, 0, 0, 1, 0, 0, 0)
        mujoco.mj_kinematics(model, data)
        rotations = [self.ft_sensor_pose(side)[1] for side in support_feet]
        sole = rotations[0]  # pelvis <- sole, while the pelvis is at the identity
        if len(rotations) == 2:
            sole = sole @ _half_rotation(rotations[0].T @ rotations[1])
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, np.ascontiguousarray(sole.T).ravel())  # flat sole: R = sole^T
        data.qpos[3:7] = quat
        mujoco.mj_kinematics(model, data)
        bottoms = []
        for side in support_feet:
            for geom in self._sole_geoms[side]:
                centre = data.geom_xpos[geom]
                half_height = model.geom_size[geom][2]
                bottoms.append(centre - np.array([0.0, 0.0, half_height]))
        lowest = min(bottom[2] for bottom in bottoms)
        middle = np.mean(bottoms, axis=0)
        data.qpos[:3] = (-middle[0], -middle[1], -lowest)
        mujoco.mj_forward(model, data)

    def hang(self, leg_angles_rad: np.ndarray | Sequence[float]) -> None:
        """Put the suspended robot at rest at these link angles (no deflection: motors = links),
        its pelvis where the gantry holds it (the MJCF fixes it; no free joint to place).

        The gears are not yet loaded: let the legs settle (step) before measuring statics.
        """
        if not self.suspended:
            raise ValueError("only a suspended robot hangs: place a standing one (place_standing)")
        angles = _leg_angles(leg_angles_rad)
        model, data = self.model, self.data
        mujoco.mj_resetData(model, data)
        self._pelvis_force_due = True  # (the reset cleared xfrc_applied)
        data.qpos[self._motor_qpos] = angles
        data.qpos[self._gear_qpos] = 0.0
        mujoco.mj_forward(model, data)


class _VaryingFriction:
    """The friction bounds of the joints whose gearbox law varies, computed for all of them at
    once (numpy: this runs every physics step) as

        F = F_c + F_s exp(-(w / w_s)^2) + mu |tau_t|

    with F_s kept for the Stribeck joints only and mu for the load-dependent ones (0 for the
    others), which is each joint's own law of sim_backend/friction.py: w its motor speed, tau_t
    its gear torque K d + D d' (only its size is read)."""

    def __init__(
        self,
        laws: Sequence[GearboxFrictionParams],
        motor_dof: np.ndarray,
        gear_qpos: np.ndarray,
        gear_dof: np.ndarray,
        stiffness_nm_per_rad: np.ndarray,
        damping_nms_per_rad: np.ndarray,
    ) -> None:
        stribeck = np.array([law.law is GearboxFriction.STRIBECK for law in laws])
        load = np.array([law.law is GearboxFriction.LOAD_DEPENDENT for law in laws])
        self.motor_dof, self.gear_qpos, self.gear_dof = motor_dof, gear_qpos, gear_dof
        self.stiffness, self.damping = stiffness_nm_per_rad, damping_nms_per_rad
        self.coulomb = np.array([law.coulomb_nm for law in laws])
        self.stribeck = np.where(stribeck, [law.stribeck_nm for law in laws], 0.0)
        self.stribeck_velocity = np.array([law.stribeck_velocity_rad_s for law in laws])
        self.load_ratio = np.where(load, [law.load_ratio for law in laws], 0.0)

    def write(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Each varying joint's bound at the present state into model.dof_frictionloss."""
        ratio = data.qvel[self.motor_dof] / self.stribeck_velocity
        torque = (
            self.stiffness * data.qpos[self.gear_qpos] + self.damping * data.qvel[self.gear_dof]
        )
        model.dof_frictionloss[self.motor_dof] = (
            self.coulomb + self.stribeck * np.exp(-ratio * ratio) + self.load_ratio * np.abs(torque)
        )


def _leg_angles(leg_angles_rad: np.ndarray | Sequence[float]) -> np.ndarray:
    angles = np.asarray(leg_angles_rad, dtype=float)
    if angles.shape != (N_LEG_JOINTS,) or not np.all(np.isfinite(angles)):
        raise ValueError(f"leg_angles_rad must be {N_LEG_JOINTS} finite angles")
    return angles


def _half_rotation(rotation: np.ndarray) -> np.ndarray:
    """The rotation about the same axis by half the angle."""
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(rotation).ravel())
    velocity = np.zeros(3)
    mujoco.mju_quat2Vel(velocity, quat, 2.0)  # half the rotation vector
    half = np.zeros(4)
    angle = float(np.linalg.norm(velocity))
    if angle < 1e-15:
        return np.eye(3)
    mujoco.mju_axisAngle2Quat(half, velocity / angle, angle)
    matrix = np.zeros(9)
    mujoco.mju_quat2Mat(matrix, half)
    return matrix.reshape(3, 3)
