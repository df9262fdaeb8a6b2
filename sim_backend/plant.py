"""MuJoCo model of the paper's 1-DoF flexible-joint testbed (Kim et al., ICRA 2018, Fig. 4a).

Structure (reference: MuJoCo modelling of a series elastic joint, serial-chain form):

    world --[hinge "motor": rotor, reflected inertia as armature, gearbox friction]--> rotor
    rotor --[hinge "gear": stiffness K, damping D; its coordinate is the deflection]--> link
    link  = a rod plus a load at the tip, swinging in a vertical plane under gravity
    world --> obstacle (a block the load can hit; its contact force is what the paper's
              force sensor measured)

The link angle an external encoder sees is theta_m + deflection. Angles: 0 = link horizontal,
positive = raising the load (the hinge axis is -y, so gravity pulls towards negative angles).

The motor hinge is driven by a `general` actuator whose force is kv*(ctrl - qvel): the
velocity-loop proportional term of the actuator's own servo (see servo.py) is then integrated
implicitly by MuJoCo's `implicitfast` integrator, which keeps a 1 ms step stable even with a stiff
velocity loop on a light rotor. The servo's outer loops compute `ctrl` every physics step.

Every physical figure is a parameter below with its unit and its source or reason.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from sim_backend.friction import (
    NEUTRAL_LOAD_FRICTION_RATIO,
    NEUTRAL_STRIBECK_FRICTION_NM,
    NEUTRAL_STRIBECK_VELOCITY_RAD_S,
    GearboxFriction,
    GearboxFrictionParams,
)

GRAVITY_M_S2 = 9.81
# The rod of TestbedPlantParams: a cylinder from the joint axis to the load's centre, the body
# `link_inertia_kg_m2` and `gravity_moment_kg_m` describe (and the configuration's [model]
# figures, 0.376 kg m^2 and 0.63 kg m, quote). It once ended at the load's surface as a capsule
# (0.66 m + caps): MuJoCo then integrated 0.363 kg m^2 and 0.614 kg m, 3.5 % and 2.5 % less than
# every figure that describes the testbed, which biased the identified K and D by as much.
# Its own inertia about its axis, m r^2 / 4 = 3e-5 kg m^2, is below 1e-4 of the link's.
ROD_RADIUS_M = 0.012


@dataclass(frozen=True)
class ObstacleParams:
    """A rigid block in the link's path, carrying a force sensor (paper Fig. 4a, item 4).

    contact_angle_rad: link angle at which the load's surface first touches the block.
    approach: +1 if the link reaches the block while its angle increases, -1 while it decreases
      (the block sits on that side of the contact angle).
    stiffness_time_constant_s: MuJoCo contact `solref` time constant; 5 ms makes the block (a
      steel block on a force sensor) deflect well under a millimetre at 100 N for this load.
    """

    contact_angle_rad: float = -0.2
    approach: int = -1
    stiffness_time_constant_s: float = 0.005
    damping_ratio: float = 1.0


@dataclass(frozen=True)
class TestbedPlantParams:
    """Physical parameters of the emulated testbed.

    Gear: K and D as the paper states for its actuators (Sec. IV-A: "K, D ... were 2000, 100").
    Motor side: the H54-200-S500-R's BLDC (Maxon, e-Manual spec table) behind a 501.923:1 gear.
      The rotor inertia is not published; 0.25 kg m^2 reflected is 9.9e-7 kg m^2 (9.9 g cm^2) at
      the rotor (0.25 / 501.923^2), the order of a 30 mm, 200 W BLDC rotor plus the first gear
      stage. An assumption.
    Gearbox friction: the spec's no-load current (1.65 A at 33.1 rpm) times the torque constant
      (44.7 N m / 9.3 A = 4.81 N m/A) is 7.9 N m of friction at 3.47 rad/s. We split it into
      Coulomb (frictionloss) and viscous parts, half each (an assumption). That is the default
      model, "coulomb-viscous"; `gearbox_friction_model` chooses another law for the Coulomb
      part (sim_backend/friction.py): "stribeck" adds `gearbox_stribeck_friction_nm` at rest,
      fading over `gearbox_stribeck_velocity_rad_s`; "load-dependent" adds
      `gearbox_load_friction_ratio` times the torque the gear transmits. A figure of a model not
      chosen stays at its neutral value.
    Link and load: not published for the paper's testbed. We choose an aluminium rod of 0.7 m and
      0.8 kg with a 0.5 kg steel load at its tip: holding it horizontal takes 6.2 N m (14 % of the
      continuous torque), and the 0.7 m lever turns the actuator's 48 N m current limit into
      ~70 N at the load, the order of force the paper's position-controlled run reached.
    """

    gear_stiffness_nm_per_rad: float = 2000.0
    gear_damping_nms_per_rad: float = 100.0
    motor_reflected_inertia_kg_m2: float = 0.25
    gearbox_coulomb_friction_nm: float = 3.95
    gearbox_viscous_friction_nms_per_rad: float = 1.14
    gearbox_friction_model: str = GearboxFriction.COULOMB_VISCOUS.value
    gearbox_stribeck_friction_nm: float = NEUTRAL_STRIBECK_FRICTION_NM
    gearbox_stribeck_velocity_rad_s: float = NEUTRAL_STRIBECK_VELOCITY_RAD_S
    gearbox_load_friction_ratio: float = NEUTRAL_LOAD_FRICTION_RATIO
    link_length_m: float = 0.7
    link_mass_kg: float = 0.8
    load_mass_kg: float = 0.5
    load_radius_m: float = 0.04
    gravity_m_s2: float = GRAVITY_M_S2
    initial_link_angle_rad: float = 0.0
    obstacle: ObstacleParams | None = None  # placed by the experiment's scenario
    physics_timestep_s: float = 0.001

    def __post_init__(self) -> None:
        positive = {
            "gear_stiffness_nm_per_rad": self.gear_stiffness_nm_per_rad,
            "motor_reflected_inertia_kg_m2": self.motor_reflected_inertia_kg_m2,
            "link_length_m": self.link_length_m,
            "link_mass_kg": self.link_mass_kg,
            "load_radius_m": self.load_radius_m,
            "physics_timestep_s": self.physics_timestep_s,
        }
        for name, value in positive.items():
            if not value > 0:
                raise ValueError(f"plant parameter {name} must be > 0, got {value}")
        nonneg = {
            "gear_damping_nms_per_rad": self.gear_damping_nms_per_rad,
            "gearbox_coulomb_friction_nm": self.gearbox_coulomb_friction_nm,
            "gearbox_viscous_friction_nms_per_rad": self.gearbox_viscous_friction_nms_per_rad,
            "load_mass_kg": self.load_mass_kg,
        }
        for name, value in nonneg.items():
            if value < 0:
                raise ValueError(f"plant parameter {name} must be >= 0, got {value}")
        self.gearbox_friction  # noqa: B018 - the friction's own checks, at construction

    @property
    def gearbox_friction(self) -> GearboxFrictionParams:
        """The gearbox's friction law and its figures (sim_backend/friction.py)."""
        return GearboxFrictionParams(
            model=self.gearbox_friction_model,  # a word: refused, named, if not a model
            coulomb_nm=self.gearbox_coulomb_friction_nm,
            stribeck_nm=self.gearbox_stribeck_friction_nm,
            stribeck_velocity_rad_s=self.gearbox_stribeck_velocity_rad_s,
            load_ratio=self.gearbox_load_friction_ratio,
        )

    @property
    def link_inertia_kg_m2(self) -> float:
        """Inertia of rod + load about the joint axis (rod: m L^2/3, a thin rod from the axis to
        the load's centre as build_mjcf builds it; load: point mass + sphere)."""
        rod = self.link_mass_kg * self.link_length_m**2 / 3.0
        load = self.load_mass_kg * (self.link_length_m**2 + 0.4 * self.load_radius_m**2)
        return rod + load

    @property
    def gravity_moment_kg_m(self) -> float:
        """m*r of link plus load: the holding torque at horizontal is this times g."""
        return self.link_mass_kg * self.link_length_m / 2.0 + self.load_mass_kg * self.link_length_m


def build_mjcf(params: TestbedPlantParams, velocity_gain_nms_per_rad: float) -> str:
    """The MJCF text of the testbed. `velocity_gain_nms_per_rad` is the servo's kv (implicit)."""
    p = params
    axis = "0 -1 0"  # positive angle raises the load
    obstacle_xml = ""
    if p.obstacle is not None:
        obstacle_xml = _obstacle_xml(p)
    rotor_inertia = 1e-6  # the armature carries the reflected inertia; the body needs a tiny mass
    return f"""
<mujoco model="flexjoint_testbed">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="{p.physics_timestep_s}" integrator="implicitfast"
          gravity="0 0 {-p.gravity_m_s2}"/>
  <worldbody>
    <body name="rotor">
      <joint name="motor" type="hinge" axis="{axis}" armature="{p.motor_reflected_inertia_kg_m2}"
             damping="{p.gearbox_viscous_friction_nms_per_rad}"
             frictionloss="{p.gearbox_coulomb_friction_nm}"/>
      <inertial pos="0 0 0" mass="0.01"
                diaginertia="{rotor_inertia} {rotor_inertia} {rotor_inertia}"/>
      <body name="link">
        <joint name="gear" type="hinge" axis="{axis}" stiffness="{p.gear_stiffness_nm_per_rad}"
               damping="{p.gear_damping_nms_per_rad}" springref="0"/>
        <geom name="rod" type="cylinder" fromto="0 0 0 {p.link_length_m} 0 0"
              size="{ROD_RADIUS_M}" mass="{p.link_mass_kg}" contype="0" conaffinity="0"/>
        <body name="load" pos="{p.link_length_m} 0 0">
          <geom name="load" type="sphere" size="{p.load_radius_m}" mass="{p.load_mass_kg}"
                contype="1" conaffinity="1" condim="1"/>
          <site name="load_site" pos="0 0 0"/>
        </body>
      </body>
    </body>
    {obstacle_xml}
  </worldbody>
  <actuator>
    <general name="servo_velocity_loop" joint="motor" gainprm="{velocity_gain_nms_per_rad}"
             biastype="affine" biasprm="0 0 {-velocity_gain_nms_per_rad}"
             ctrllimited="false" forcelimited="true" forcerange="-1000 1000"/>
  </actuator>
</mujoco>
"""


def _obstacle_xml(p: TestbedPlantParams) -> str:
    """A block whose lower face touches the load's top when the link reaches contact_angle_rad."""
    assert p.obstacle is not None
    angle = p.obstacle.contact_angle_rad
    # Load centre at the contact angle; the block sits just beyond it along the swing direction.
    cx, cz = p.link_length_m * math.cos(angle), p.link_length_m * math.sin(angle)
    # direction in which the load travels when it reaches the block
    tangent = p.obstacle.approach * np.array([-math.sin(angle), math.cos(angle)])
    half_thickness = 0.05
    centre = np.array([cx, cz]) + tangent * (p.load_radius_m + half_thickness)
    # Rotate the block so that its face is perpendicular to the swing direction.
    block_angle = angle
    quat = f"{math.cos(block_angle / 2)} 0 {-math.sin(block_angle / 2)} 0"
    solref = f"{p.obstacle.stiffness_time_constant_s} {p.obstacle.damping_ratio}"
    return (
        f'<body name="obstacle" pos="{centre[0]} 0 {centre[1]}" quat="{quat}">'
        f'<geom name="obstacle" type="box" size="0.08 0.06 {half_thickness}" '
        f'contype="1" conaffinity="1" condim="1" solref="{solref}"/></body>'
    )


@dataclass
class PlantState:
    """True physical state (SI); the emulated sensors quantise it, the log may show it."""

    time_s: float
    motor_angle_rad: float
    motor_velocity_rad_s: float
    link_angle_rad: float
    link_velocity_rad_s: float
    motor_torque_nm: float
    contact_force_n: float


class TestbedPlant:
    """The MuJoCo testbed: set the servo's velocity command, step, read the true state."""

    def __init__(self, params: TestbedPlantParams, velocity_gain_nms_per_rad: float) -> None:
        self.params = params
        self.model = mujoco.MjModel.from_xml_string(build_mjcf(params, velocity_gain_nms_per_rad))
        self.data = mujoco.MjData(self.model)
        self._motor_qpos = self.model.jnt_qposadr[self.model.joint("motor").id]
        self._gear_qpos = self.model.jnt_qposadr[self.model.joint("gear").id]
        self._motor_dof = self.model.jnt_dofadr[self.model.joint("motor").id]
        self._gear_dof = self.model.jnt_dofadr[self.model.joint("gear").id]
        self._load_body = self.model.body("load").id
        self._load_geom = self.model.geom("load").id
        self._obstacle_geom = self.model.geom("obstacle").id if params.obstacle is not None else -1
        self._actuator = 0
        self._contact_wrench = np.zeros(6)
        self._external_force_n = 0.0
        self._brake_damping_nms_per_rad = 0.0
        self._torque_limit_nm: float | None = None  # as last written to MuJoCo
        self._load_force_applied = True  # xfrc_applied of the load may hold a push
        self._brake_applied = True  # qfrc_applied of the motor may hold a brake's force
        # a friction law other than the constant Coulomb bound: rewritten before every step
        self._friction = params.gearbox_friction if params.gearbox_friction.varies else None
        self.settle_statically()

    # --- state -------------------------------------------------------------------------------
    @property
    def time_s(self) -> float:
        return float(self.data.time)

    @property
    def motor_angle_rad(self) -> float:
        return float(self.data.qpos[self._motor_qpos])

    @property
    def motor_velocity_rad_s(self) -> float:
        return float(self.data.qvel[self._motor_dof])

    @property
    def deflection_rad(self) -> float:
        return float(self.data.qpos[self._gear_qpos])

    @property
    def link_angle_rad(self) -> float:
        """What the external link encoder measures: motor angle plus gear deflection."""
        return float(self.data.qpos[self._motor_qpos] + self.data.qpos[self._gear_qpos])

    @property
    def link_velocity_rad_s(self) -> float:
        return float(self.data.qvel[self._motor_dof] + self.data.qvel[self._gear_dof])

    @property
    def gear_torque_nm(self) -> float:
        """The torque the gear carries from the rotor to the link: K deflection + D its rate."""
        p, data = self.params, self.data
        return float(
            p.gear_stiffness_nm_per_rad * data.qpos[self._gear_qpos]
            + p.gear_damping_nms_per_rad * data.qvel[self._gear_dof]
        )

    @property
    def motor_torque_nm(self) -> float:
        """Torque the servo's motor produces at the output (actuator force, after its limit)."""
        return float(self.data.actuator_force[self._actuator])

    def contact_force_n(self) -> float:
        """Normal force between the load and the obstacle (the paper's force sensor reading)."""
        if self._obstacle_geom < 0:
            return 0.0
        total = 0.0
        for i in range(self.data.ncon):
            contact = self.data.contact[i]
            if {contact.geom1, contact.geom2} == {self._load_geom, self._obstacle_geom}:
                mujoco.mj_contactForce(self.model, self.data, i, self._contact_wrench)
                total += abs(self._contact_wrench[0])
        return total

    def state(self) -> PlantState:
        return PlantState(
            time_s=self.time_s,
            motor_angle_rad=self.motor_angle_rad,
            motor_velocity_rad_s=self.motor_velocity_rad_s,
            link_angle_rad=self.link_angle_rad,
            link_velocity_rad_s=self.link_velocity_rad_s,
            motor_torque_nm=self.motor_torque_nm,
            contact_force_n=self.contact_force_n(),
        )

    # --- inputs ------------------------------------------------------------------------------
    def set_servo(self, velocity_command_rad_s: float, torque_limit_nm: float) -> None:
        """The servo's velocity-loop input this step, and its torque (current) limit."""
        if torque_limit_nm != self._torque_limit_nm:  # (it changes with the registers only)
            self._torque_limit_nm = torque_limit_nm
            self.model.actuator_forcerange[self._actuator] = (-torque_limit_nm, torque_limit_nm)
        self.data.ctrl[self._actuator] = velocity_command_rad_s

    def set_brake(self, brake_damping_nms_per_rad: float) -> None:
        """The dynamic brake's motor-side damping (shorted windings while torque is off; 0 while
        the servo drives the motor)."""
        self._brake_damping_nms_per_rad = brake_damping_nms_per_rad

    def set_external_force(self, force_n: float) -> None:
        """A push on the load, perpendicular to the link, positive towards increasing angle."""
        self._external_force_n = force_n

    def step(self) -> None:
        """Advance one physics step. (A push and the brake are written only while they act,
        and zeroed once after: MuJoCo leaves xfrc_applied and qfrc_applied as written.)"""
        data = self.data
        if self._external_force_n != 0.0:
            data.xfrc_applied[self._load_body, :] = 0.0
            angle = self.link_angle_rad
            direction = np.array([-math.sin(angle), 0.0, math.cos(angle)])
            data.xfrc_applied[self._load_body, :3] = self._external_force_n * direction
            self._load_force_applied = True
        elif self._load_force_applied:
            data.xfrc_applied[self._load_body, :] = 0.0
            self._load_force_applied = False
        if self._brake_damping_nms_per_rad != 0.0:
            data.qfrc_applied[self._motor_dof] = (
                -self._brake_damping_nms_per_rad * data.qvel[self._motor_dof]
            )
            self._brake_applied = True
        elif self._brake_applied:
            data.qfrc_applied[self._motor_dof] = 0.0
            self._brake_applied = False
        if self._friction is not None:
            self.model.dof_frictionloss[self._motor_dof] = self._friction.loss_nm(
                float(data.qvel[self._motor_dof]), self.gear_torque_nm
            )
        mujoco.mj_step(self.model, data)

    def settle_statically(self) -> None:
        """Start with the gear pre-deflected by gravity so the link does not drop at t = 0.

        Static balance of (1)-(3): K * deflection = -m g r cos(theta).
        """
        p = self.params
        gravity_torque = p.gravity_m_s2 * p.gravity_moment_kg_m * math.cos(p.initial_link_angle_rad)
        deflection = -gravity_torque / p.gear_stiffness_nm_per_rad
        self.data.qpos[self._motor_qpos] = p.initial_link_angle_rad - deflection
        self.data.qpos[self._gear_qpos] = deflection
        mujoco.mj_forward(self.model, self.data)
