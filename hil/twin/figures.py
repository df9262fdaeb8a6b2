"""The emulator's figures a twin fits, for the testbed's joint, and the configuration they make.

Each figure is one the emulator already reads (`[emulator] plant`, `servo`, the zero errors),
so a twin is an ordinary configuration: the recorded one with its `[emulator]` section made to
match. `[model]` (the controller's nominal model) and every other section stay as recorded, so
that the recorded controller runs on the twin as it ran on the robot.

The link: its inertia I about the joint and its gravity moment m r are what the data determine;
the emulated link is a rod from the axis to a load (sim_backend/plant.py), so the twin keeps the
recorded link length L and load radius r and fits the rod's and the load's masses, of which
I and m r are linear (`link_figures`; any positive pair of masses is a link, so the fit never
leaves the emulator's reach):

    I   = m_rod (L^2 / 3 + R^2 / 4) + m_load (L^2 + 0.4 r^2)     (MuJoCo's cylinder of radius R)
    m r = m_rod L / 2 + m_load L

The servo: the emulator scales each gain with its register (sim_backend/servo.py); the fit sees
the gains at the registers in force, so the twin's SI figures are those at the default
registers that give the fitted gains at the recorded ones.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

from hil.config import Config
from hil.vocabulary import Robot
from hil.wiring.emulation import plant_servo_noise
from sim_backend.friction import GearboxFriction
from sim_backend.plant import ROD_RADIUS_M, TestbedPlantParams
from sim_backend.servo import H54ServoParams


class Part(enum.Enum):
    """Where a figure lives in the configuration."""

    PLANT = "plant"  # [emulator] plant
    SERVO = "servo"  # [emulator] servo (at the default registers)
    ZERO = "zero"  # [emulator] motor_zero_error_rad / link_zero_error_rad


class Scale(enum.Enum):
    LOG = "log"  # a positive figure, fitted as log(value / start)
    LINEAR = "linear"  # fitted as (value - start) / step


@dataclass(frozen=True)
class Figure:
    key: str
    unit: str
    part: Part
    scale: Scale
    step: float = 1.0  # LINEAR: the figure's unit of change in fit coordinates
    lower: float = -math.inf  # LINEAR: its bound


FIGURES: dict[str, Figure] = {
    f.key: f
    for f in (
        Figure("gear_stiffness_nm_per_rad", "N m/rad", Part.PLANT, Scale.LOG),
        Figure("gear_damping_nms_per_rad", "N m s/rad", Part.PLANT, Scale.LOG),
        Figure("position_gain_per_s", "1/s", Part.SERVO, Scale.LOG),
        Figure("velocity_gain_nms_per_rad", "N m s/rad", Part.SERVO, Scale.LOG),
        Figure("velocity_integral_time_s", "s", Part.SERVO, Scale.LOG),
        Figure("motor_reflected_inertia_kg_m2", "kg m^2", Part.PLANT, Scale.LOG),
        Figure("gearbox_coulomb_friction_nm", "N m", Part.PLANT, Scale.LINEAR, 1.0, 0.0),
        Figure(
            "gearbox_viscous_friction_nms_per_rad", "N m s/rad", Part.PLANT, Scale.LINEAR, 1.0, 0.0
        ),
        Figure("gearbox_stribeck_friction_nm", "N m", Part.PLANT, Scale.LINEAR, 1.0, 0.0),
        Figure("gearbox_stribeck_velocity_rad_s", "rad/s", Part.PLANT, Scale.LOG),
        Figure("gearbox_load_friction_ratio", "", Part.PLANT, Scale.LINEAR, 0.1, 0.0),
        Figure("link_mass_kg", "kg", Part.PLANT, Scale.LOG),
        Figure("load_mass_kg", "kg", Part.PLANT, Scale.LOG),
        Figure("motor_zero_error_rad", "rad", Part.ZERO, Scale.LINEAR, 1e-3),
        Figure("link_zero_error_rad", "rad", Part.ZERO, Scale.LINEAR, 1e-3),
    )
}

# The figures every fit has, and each friction model's own.
COMMON = (
    "gear_stiffness_nm_per_rad",
    "gear_damping_nms_per_rad",
    "position_gain_per_s",
    "velocity_gain_nms_per_rad",
    "velocity_integral_time_s",
    "motor_reflected_inertia_kg_m2",
    "gearbox_coulomb_friction_nm",
    "gearbox_viscous_friction_nms_per_rad",
    "link_mass_kg",
    "load_mass_kg",
    "motor_zero_error_rad",
    "link_zero_error_rad",
)
FRICTION_FIGURES: dict[GearboxFriction, tuple[str, ...]] = {
    GearboxFriction.COULOMB_VISCOUS: (),
    GearboxFriction.STRIBECK: ("gearbox_stribeck_friction_nm", "gearbox_stribeck_velocity_rad_s"),
    GearboxFriction.LOAD_DEPENDENT: ("gearbox_load_friction_ratio",),
}
SERVO_REGISTERS = {
    "position_gain_per_s": ("position_p_gain", "default_position_gain_register"),
    "velocity_gain_nms_per_rad": ("velocity_p_gain", "default_velocity_p_gain_register"),
    "velocity_integral_time_s": ("velocity_i_gain", "default_velocity_i_gain_register"),
}


def single_joint(config: Config) -> None:
    """The twin fits the testbed's plant, one for all its joints: one joint, then."""
    if config.model.robot != Robot.TESTBED or len(config.joints) != 1:
        raise ValueError(
            "hil twin fits the 1-DoF testbed's joint (one [[joint]], [model] robot = "
            f"'{Robot.TESTBED}') and DYROS-JET's legs (hil/twin/legs.py); this configuration "
            f"has {len(config.joints)} joints of {config.model.robot!r}"
        )


def _in_force(config: Config, servo: H54ServoParams) -> dict[str, float]:
    """The servo's gains at the registers in force (the [[joint]]'s, else the defaults)."""
    joint = config.joints[0]
    registers = {
        name: getattr(joint, reg) or getattr(servo, default)
        for name, (reg, default) in SERVO_REGISTERS.items()
    }
    cascade = servo.cascade_at(
        registers["position_gain_per_s"],
        registers["velocity_gain_nms_per_rad"],
        registers["velocity_integral_time_s"],
    )
    return {
        "position_gain_per_s": cascade.position_gain_per_s,
        "velocity_gain_nms_per_rad": cascade.velocity_gain_nms_per_rad,
        "velocity_integral_time_s": cascade.velocity_integral_time_s,
    }


def link_figures(plant: TestbedPlantParams) -> tuple[float, float]:
    """(I, m r) of the emulated link as MuJoCo integrates it (the rod as a cylinder)."""
    (a_rod, a_load), (b_rod, b_load) = link_coefficients(plant)
    rod, load = plant.link_mass_kg, plant.load_mass_kg
    return a_rod * rod + a_load * load, b_rod * rod + b_load * load


def link_coefficients(plant: TestbedPlantParams) -> tuple[tuple[float, float], ...]:
    """((dI/dm_rod, dI/dm_load), (d(m r)/dm_rod, d(m r)/dm_load)) on the plant's link."""
    length, radius = plant.link_length_m, plant.load_radius_m
    return (
        (length**2 / 3.0 + ROD_RADIUS_M**2 / 4.0, length**2 + 0.4 * radius**2),
        (length / 2.0, length),
    )


def figures_of(config: Config) -> dict[str, float]:
    """Every figure of FIGURES as the emulator of `config` has it."""
    single_joint(config)
    plant, servo, _ = plant_servo_noise(config)
    motor_error, link_error = config.emulator.zero_errors(1)
    out = {key: float(getattr(plant, key)) for key, f in FIGURES.items() if f.part is Part.PLANT}
    out.update(_in_force(config, servo))
    out["motor_zero_error_rad"], out["link_zero_error_rad"] = motor_error[0], link_error[0]
    return out


def friction_of(config: Config) -> GearboxFriction:
    plant, _, _ = plant_servo_noise(config)
    return plant.gearbox_friction.law


def twin_config(base: Config, figures: dict[str, float], friction: GearboxFriction) -> Config:
    """`base` with its [emulator] made to have these figures and this friction model (a figure
    not given keeps the base's)."""
    single_joint(base)
    current = figures_of(base)
    values = {**current, **figures}
    plant_now, servo_now, _ = plant_servo_noise(base)
    plant = dict(base.emulator.plant)
    for key, figure in FIGURES.items():
        if figure.part is Part.PLANT:
            plant[key] = float(values[key])
    plant["gearbox_friction_model"] = friction.value
    for key in (
        FRICTION_FIGURES[GearboxFriction.STRIBECK]
        + FRICTION_FIGURES[GearboxFriction.LOAD_DEPENDENT]
    ):
        if key not in FRICTION_FIGURES[friction]:
            plant.pop(key, None)  # a figure the model does not read stays neutral
    servo = dict(base.emulator.servo)
    in_force = _in_force(base, servo_now)
    for key in SERVO_REGISTERS:
        # the SI figure at the default registers scales as the gain at the registers in force
        default = float(getattr(servo_now, key))
        servo[key] = default * values[key] / in_force[key]
    return base.changed(
        "emulator",
        plant=plant,
        servo=servo,
        motor_zero_error_rad=float(values["motor_zero_error_rad"]),
        link_zero_error_rad=float(values["link_zero_error_rad"]),
    )
