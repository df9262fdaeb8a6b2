"""The emulated DYROS-JET's physical parameters: the TRUTH of a run (the controller's model is
nominal and separate; a run can make them differ to test robustness).

Every default is the published robot (the URDF's figures) with the paper's gear (K = 2000 N m/rad,
D = 100 N m s/rad, Kim et al., Sec. IV-A: the humanoid uses the testbed's actuator modules) and
the testbed's H54 motor side (sim_backend.plant.TestbedPlantParams: reflected rotor inertia
0.25 kg m^2, gearbox friction 3.95 N m Coulomb + 1.14 N m s/rad viscous, assumptions documented
there). Per-joint figures are 12-tuples in the lab's leg order (L hip yaw, roll, pitch, knee,
ankle pitch, ankle roll, then R); a scalar means the same for all 12.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Literal

from sim_backend.friction import (
    NEUTRAL_LOAD_FRICTION_RATIO,
    NEUTRAL_STRIBECK_FRICTION_NM,
    NEUTRAL_STRIBECK_VELOCITY_RAD_S,
    GearboxFriction,
    GearboxFrictionParams,
)
from sim_backend.servo import H54ServoParams

# DYROS-JET's leg joints and upper body: the emulator's one copy (the controller holds its own,
# controller/humanoid/leg_model.py; tests/hil/test_dyros_jet_facts.py keeps them equal).
LEFT_LEG_JOINT_NAMES: tuple[str, ...] = (
    "L_HipYaw",
    "L_HipRoll",
    "L_HipPitch",
    "L_KneePitch",
    "L_AnklePitch",
    "L_AnkleRoll",
)
LEG_JOINT_NAMES: tuple[str, ...] = LEFT_LEG_JOINT_NAMES + tuple(
    "R" + name[1:] for name in LEFT_LEG_JOINT_NAMES
)
N_LEG_JOINTS = len(LEG_JOINT_NAMES)
FOOT_LINK_NAMES: tuple[str, str] = ("L_AnkleRoll_Link", "R_AnkleRoll_Link")
PELVIS_LINK_NAME = "base_link"
KNEE_INDICES = (3, 9)

# The lab's "Init Walking" upper body (psh117/dyros_jet, dyros_jet_gui task_window.cpp,
# on_button_walk_init_wholebody_clicked), rad: the waist and arms are welded at these angles.
# The controller's LegModel locks the same joints at the same angles by default.
LAB_WALK_INIT_UPPER_BODY_RAD: Mapping[str, float] = {
    "WaistPitch": 0.0,
    "WaistYaw": 0.0,
    "L_ShoulderPitch": 0.6981317008,
    "L_ShoulderRoll": -1.6580627893,
    "L_ShoulderYaw": -1.3962634016,
    "L_ElbowRoll": -1.9198621771,
    "L_WristYaw": 0.0,
    "L_WristRoll": -1.2217304764,
    "L_HandYaw": -0.1745329252,
    "R_ShoulderPitch": -0.6981317008,
    "R_ShoulderRoll": 1.6580627893,
    "R_ShoulderYaw": 1.3962634016,
    "R_ElbowRoll": 1.9198621771,
    "R_WristYaw": 0.0,
    "R_WristRoll": 1.2217304764,
    "R_HandYaw": 0.17453292519,
}

# The lab's knee servo gain: Kp = 18 1/s (walking_controller.cpp, motor_k_mat(3,3) and (9,9)).
# Position P Gain (594) scales the emulated firmware's Kpp linearly, register 32 = 10 1/s
# (sim_backend.servo), so the knees are set to 58 -> 18.1 1/s; the other joints keep 32.
LAB_KNEE_POSITION_GAIN_REGISTER = 58


# Torque Limit (30, EEPROM) of the leg actuators. The e-Manual's initial value 620 (x 16.11328 mA
# = 10.0 A, x 4.81 N m/A = 48 N m at the output) does not hold DYROS-JET on one leg with the
# published figures: in single support the stance hip roll and knee carry ~62 N m (more while the
# servo lags), the cap clips them and the overload protection (90 % of the cap held for 1.5 s)
# shuts them down (tests/sim_backend/test_humanoid_robot.py shows it). The lab's configuration is
# not published. ASSUMPTION: the emulated robot's legs are configured to 1240 (20.0 A, 96 N m),
# within the item's range 0..1860; a host configuration for DYROS-JET should write the same.
DYROS_JET_LEG_TORQUE_LIMIT_REGISTER = 1240


def leg_eeprom_overrides() -> dict[str, int]:
    """EEPROM items of each emulated leg actuator as the DYROS-JET emulator configures them."""
    return {"Torque Limit": DYROS_JET_LEG_TORQUE_LIMIT_REGISTER}


def _per_joint(value: float | tuple[float, ...], name: str) -> tuple[float, ...]:
    values = (float(value),) * N_LEG_JOINTS if isinstance(value, int | float) else tuple(value)
    if len(values) != N_LEG_JOINTS or not all(math.isfinite(v) for v in values):
        raise ValueError(f"{name} needs one finite value or {N_LEG_JOINTS} finite values")
    return values


def _per_joint_model(value: str | tuple[str, ...]) -> tuple[str, ...]:
    """gearbox_friction_model as 12 words, each one of GearboxFriction's (refused by name)."""
    words = (value,) * N_LEG_JOINTS if isinstance(value, str) else tuple(value)
    if len(words) != N_LEG_JOINTS:
        raise ValueError(f"gearbox_friction_model needs one word or {N_LEG_JOINTS} words")
    laws = []
    for joint, word in zip(LEG_JOINT_NAMES, words, strict=True):
        try:
            laws.append(GearboxFriction(word).value)
        except ValueError:
            choices = ", ".join(repr(m.value) for m in GearboxFriction)
            raise ValueError(
                f"gearbox_friction_model must be one of {choices}, got {word!r} ({joint})"
            ) from None
    return tuple(laws)


# The servo's SI figures a run may give per joint (RobotTruthParams), each replacing the
# H54ServoParams field of the same name.
SERVO_FIGURES = ("position_gain_per_s", "velocity_gain_nms_per_rad", "velocity_integral_time_s")

# The gearbox friction figures beyond Coulomb and viscous (sim_backend/friction.py), per joint.
FRICTION_FIGURES = (
    "gearbox_stribeck_friction_nm",
    "gearbox_stribeck_velocity_rad_s",
    "gearbox_load_friction_ratio",
)


def lab_position_gain_registers() -> tuple[int, ...]:
    """Position P Gain (594) per leg joint: 32 (10 1/s) except the knees (58, ~18 1/s)."""
    return tuple(
        LAB_KNEE_POSITION_GAIN_REGISTER if i in KNEE_INDICES else 32 for i in range(N_LEG_JOINTS)
    )


@dataclass(frozen=True)
class ContactParams:
    """Sole-ground contact: Coulomb friction and MuJoCo's solref (time constant, damping ratio).

    friction 1.0: rubber soles on a floor (the lab's MuJoCo model uses 1.0). solref 20 ms, 1:
    MuJoCo's default soft contact, 20 x the 1 ms step (a stable choice for `implicitfast`).

    friction_cone / friction_impedance_ratio: MuJoCo's `cone` and `impratio`. MuJoCo's friction
    constraints are soft like its normal ones: at MuJoCo's defaults (pyramidal cone, impratio 1,
    `ContactParams.creeping()`) a sole loaded far inside its friction cone still creeps.
    Measured (walking-ready posture, gravity-compensated goals held;
    tests/sim_backend/test_humanoid_contact_creep.py): the splayed legs push each sole outward
    by ~4 N against mu Fz = 245 N, and the feet spread by 1.75 mm in 3 s, ~0.6 mm/s, for ever;
    rubber soles on a floor stick. The default (elliptic cone, impratio 100: MuJoCo's remedy,
    impratio > 1 makes the friction dimensions harder than the normal one, elliptic cones only;
    the MuJoCo Menagerie's legged robots use 100) spreads them 0.02 mm in 3 s; the normal
    contact (solref) is the same in both. With sticking soles the internal force of double
    support stays where the settling left it (statically indeterminate, as on a real robot):
    tests judge double support modulo that internal force.
    """

    friction: float = 1.0
    time_constant_s: float = 0.02
    damping_ratio: float = 1.0
    friction_cone: Literal["elliptic", "pyramidal"] = "elliptic"
    friction_impedance_ratio: float = 100.0

    @classmethod
    def sticking(cls) -> ContactParams:
        """Soles that stick inside their friction cone (elliptic cone, impratio 100): the
        default."""
        return cls(friction_cone="elliptic", friction_impedance_ratio=100.0)

    @classmethod
    def creeping(cls) -> ContactParams:
        """MuJoCo's own defaults (pyramidal cone, impratio 1): loaded soles creep ~0.6 mm/s."""
        return cls(friction_cone="pyramidal", friction_impedance_ratio=1.0)

    def __post_init__(self) -> None:
        if self.friction_cone not in ("elliptic", "pyramidal"):
            raise ValueError(
                f"friction_cone must be elliptic or pyramidal, got {self.friction_cone!r}"
            )
        ratio = self.friction_impedance_ratio
        if not (math.isfinite(ratio) and ratio >= 1.0):
            raise ValueError(f"friction_impedance_ratio must be >= 1, got {ratio}")
        if ratio != 1.0 and self.friction_cone != "elliptic":
            raise ValueError("MuJoCo applies impratio only with the elliptic cone")


@dataclass(frozen=True)
class RobotTruthParams:
    """The emulated robot's physics (see the module docstring). All overridable for robustness.

    mass_scale: every link's mass and inertia times this (1 = published).
    com_offset_link / com_offset_m: a shift of one link's centre of mass (default the torso,
        14.1 kg of the 50 kg), e.g. a payload the controller does not know of.
    upper_body_angles_rad: where the waist and arm joints are welded.
    gearbox_friction_model: the gearbox friction law per joint (sim_backend/friction.py:
        "coulomb-viscous", "stribeck", "load-dependent"), with its figures
        gearbox_stribeck_friction_nm, gearbox_stribeck_velocity_rad_s and
        gearbox_load_friction_ratio (a figure a joint's law does not read stays at its neutral
        value for that joint: give a 12-tuple when the joints' laws differ). The default
        (coulomb-viscous everywhere) is MuJoCo's constant frictionloss, nothing per step.
    servo: the H54 firmware's SI figures (one for all joints, or 12).
    position_gain_per_s / velocity_gain_nms_per_rad / velocity_integral_time_s: the servo's
        Kpp, kv and Ti per joint (None: the `servo`'s; a float: all joints; a 12-tuple), at
        the default registers as H54ServoParams' are (the registers still scale them).
    position_gain_registers: Position P Gain (594) per joint at power-on (the lab's knee
        Kp = 18: see LAB_KNEE_POSITION_GAIN_REGISTER). A REBOOT returns a device's RAM to the
        e-Manual default (32): the host re-writes it, as on the real robot.
    physics_timestep_s: MuJoCo step (implicitfast); the firmware runs once per step.
    """

    gear_stiffness_nm_per_rad: float | tuple[float, ...] = 2000.0
    gear_damping_nms_per_rad: float | tuple[float, ...] = 100.0
    motor_reflected_inertia_kg_m2: float | tuple[float, ...] = 0.25
    gearbox_coulomb_friction_nm: float | tuple[float, ...] = 3.95
    gearbox_viscous_friction_nms_per_rad: float | tuple[float, ...] = 1.14
    gearbox_friction_model: str | tuple[str, ...] = GearboxFriction.COULOMB_VISCOUS.value
    gearbox_stribeck_friction_nm: float | tuple[float, ...] = NEUTRAL_STRIBECK_FRICTION_NM
    gearbox_stribeck_velocity_rad_s: float | tuple[float, ...] = NEUTRAL_STRIBECK_VELOCITY_RAD_S
    gearbox_load_friction_ratio: float | tuple[float, ...] = NEUTRAL_LOAD_FRICTION_RATIO
    mass_scale: float = 1.0
    com_offset_link: str = "WaistYaw_Link"
    com_offset_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    upper_body_angles_rad: Mapping[str, float] = field(
        default_factory=lambda: dict(LAB_WALK_INIT_UPPER_BODY_RAD)
    )
    servo: H54ServoParams | tuple[H54ServoParams, ...] = field(default_factory=H54ServoParams)
    position_gain_per_s: float | tuple[float, ...] | None = None
    velocity_gain_nms_per_rad: float | tuple[float, ...] | None = None
    velocity_integral_time_s: float | tuple[float, ...] | None = None
    position_gain_registers: tuple[int, ...] = field(default_factory=lab_position_gain_registers)
    contact: ContactParams = field(default_factory=ContactParams)
    physics_timestep_s: float = 0.001
    gravity_m_s2: float = 9.81

    def __post_init__(self) -> None:
        for name in (
            "gear_stiffness_nm_per_rad",
            "gear_damping_nms_per_rad",
            "motor_reflected_inertia_kg_m2",
            "gearbox_coulomb_friction_nm",
            "gearbox_viscous_friction_nms_per_rad",
        ):
            values = _per_joint(getattr(self, name), name)
            if any(v < 0 for v in values) or (
                name in ("gear_stiffness_nm_per_rad", "motor_reflected_inertia_kg_m2")
                and any(v <= 0 for v in values)
            ):
                raise ValueError(f"{name} must be positive, got {values}")
            object.__setattr__(self, name, values)
        servos = (
            (self.servo,) * N_LEG_JOINTS
            if isinstance(self.servo, H54ServoParams)
            else (tuple(self.servo))
        )
        if len(servos) != N_LEG_JOINTS:
            raise ValueError(f"servo needs one H54ServoParams or {N_LEG_JOINTS}")
        object.__setattr__(self, "servo", servos)
        for name in SERVO_FIGURES:
            if getattr(self, name) is not None:
                values = _per_joint(getattr(self, name), name)
                if any(v <= 0 for v in values):
                    raise ValueError(f"{name} must be positive, got {values}")
                object.__setattr__(self, name, values)
        object.__setattr__(
            self, "gearbox_friction_model", _per_joint_model(self.gearbox_friction_model)
        )
        for name in FRICTION_FIGURES:
            object.__setattr__(self, name, _per_joint(getattr(self, name), name))
        for joint, name in enumerate(LEG_JOINT_NAMES):
            try:  # the friction's and the servo's own checks (a figure its law does not read)
                self.gearbox_friction(joint)
                self.servo_params(joint)
            except ValueError as error:
                raise ValueError(f"{name}: {error}") from None
        if len(self.position_gain_registers) != N_LEG_JOINTS:
            raise ValueError(f"position_gain_registers needs {N_LEG_JOINTS} entries")
        if not (math.isfinite(self.mass_scale) and self.mass_scale > 0):
            raise ValueError(f"mass_scale must be > 0, got {self.mass_scale}")
        if not (math.isfinite(self.physics_timestep_s) and 0 < self.physics_timestep_s <= 0.002):
            raise ValueError(
                f"physics_timestep_s must be in (0, 2 ms] (implicitfast, measured stable), got "
                f"{self.physics_timestep_s}"
            )
        if len(self.com_offset_m) != 3:
            raise ValueError("com_offset_m needs 3 entries")

    def servo_params(self, joint: int) -> H54ServoParams:
        """One joint's firmware figures: its `servo` with any per-joint Kpp, kv, Ti put in."""
        servos = self.servo
        assert isinstance(servos, tuple)
        changes = {
            name: values[joint]
            for name in SERVO_FIGURES
            if (values := getattr(self, name)) is not None
        }
        return replace(servos[joint], **changes) if changes else servos[joint]

    def gearbox_friction(self, joint: int) -> GearboxFrictionParams:
        """One joint's gearbox friction law and figures (sim_backend/friction.py); its checks
        refuse a figure the joint's law does not read, naming the key."""
        models = self.gearbox_friction_model
        assert isinstance(models, tuple)
        return GearboxFrictionParams(
            model=models[joint],
            coulomb_nm=self.per_joint("gearbox_coulomb_friction_nm")[joint],
            stribeck_nm=self.per_joint("gearbox_stribeck_friction_nm")[joint],
            stribeck_velocity_rad_s=self.per_joint("gearbox_stribeck_velocity_rad_s")[joint],
            load_ratio=self.per_joint("gearbox_load_friction_ratio")[joint],
        )

    def per_joint(self, name: str) -> tuple[float, ...]:
        """A per-joint figure as a 12-tuple (after validation every such field is one)."""
        value = getattr(self, name)
        assert isinstance(value, tuple)
        return value
