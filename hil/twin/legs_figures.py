"""The emulator's figures a twin of DYROS-JET's legs fits, and the configuration they make.

Per leg joint (the lab's order), the figures the emulated humanoid reads from `[emulator]`
(sim_backend/humanoid/params.py `RobotTruthParams`, each key a list of 12): the gear's K and D,
the servo's cascade (`position_gain_per_s`, `velocity_gain_nms_per_rad`,
`velocity_integral_time_s`: SI figures at the default registers, as `[emulator] servo`'s; the
registers in force scale them on the robot as on the emulator), the rotor's reflected inertia,
the gearbox's friction (its model per joint and the model's figures), and the two encoders'
zero errors (`motor_zero_error_rad`, `link_zero_error_rad`, lists of 12). One figure for the
whole robot: `mass_scale`, every link's mass and inertia (the legs' and the upper body's) times
it - the inertia and gravity moments the joints carry, which a suspended leg's motion and
current see.

What stays as recorded: `[model]` (the controller's nominal model) and every other section, so
that the recorded controller runs on the twin as it ran on the robot; the robot's geometry
(the URDF); the soles' contact; the upper body's locked posture.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hil.config import Config
from hil.twin.figures import COMMON, FIGURES, FRICTION_FIGURES, Figure, Part, Scale
from hil.vocabulary import Robot
from sim_backend.friction import (
    NEUTRAL_LOAD_FRICTION_RATIO,
    NEUTRAL_STRIBECK_FRICTION_NM,
    NEUTRAL_STRIBECK_VELOCITY_RAD_S,
    GearboxFriction,
)

# The figures every leg joint has: the testbed joint's but its link's masses (the legs' links
# are the URDF's, scaled by `mass_scale`); FIGURES gives each one's unit and fit scale.
JOINT_FIGURES = tuple(k for k in COMMON if k not in ("link_mass_kg", "load_mass_kg"))
SERVO_FIGURES = ("position_gain_per_s", "velocity_gain_nms_per_rad", "velocity_integral_time_s")
ZERO_FIGURES = ("motor_zero_error_rad", "link_zero_error_rad")
MASS_SCALE = Figure("mass_scale", "", Part.PLANT, Scale.LOG)
NEUTRAL = {
    "gearbox_stribeck_friction_nm": NEUTRAL_STRIBECK_FRICTION_NM,
    "gearbox_stribeck_velocity_rad_s": NEUTRAL_STRIBECK_VELOCITY_RAD_S,
    "gearbox_load_friction_ratio": NEUTRAL_LOAD_FRICTION_RATIO,
}
MODEL_FIGURES = tuple(NEUTRAL)  # every friction model's own figures


def figure(key: str) -> Figure:
    return MASS_SCALE if key == MASS_SCALE.key else FIGURES[key]


@dataclass
class LegFigures:
    """Every figure of the legs' emulator: per joint arrays of 12, the friction model per joint,
    the robot's mass scale."""

    joints: dict[str, np.ndarray]  # JOINT_FIGURES and MODEL_FIGURES, (12,) each
    models: list[GearboxFriction]
    mass_scale: float
    names: tuple[str, ...] = field(default=())

    def copy(self) -> LegFigures:
        return LegFigures(
            {k: v.copy() for k, v in self.joints.items()},
            list(self.models),
            self.mass_scale,
            self.names,
        )

    def keys_of(self, joint: int) -> tuple[str, ...]:
        """The figures joint `joint` has with its friction model."""
        return JOINT_FIGURES + FRICTION_FIGURES[self.models[joint]]

    def with_model(self, joint: int, model: GearboxFriction, start: dict[str, float]) -> None:
        """Give joint `joint` friction model `model`, its own figures from `start` (the others
        back to neutral)."""
        self.models[joint] = model
        for key in MODEL_FIGURES:
            own = key in FRICTION_FIGURES[model]
            self.joints[key][joint] = start.get(key, NEUTRAL[key]) if own else NEUTRAL[key]


def legs_robot(config: Config) -> None:
    """The legs' twin is DYROS-JET's: refuse another robot, saying which fits what."""
    if config.model.robot is not Robot.DYROS_JET:
        raise ValueError(
            f"the legs' twin fits DYROS-JET's 12 leg joints; this configuration is of "
            f"{config.model.robot!r}"
        )


def _truth(config: Config):  # -> RobotTruthParams (sim_backend: imported when used)
    from hil.wiring.emulation import plant_servo_noise
    from sim_backend.humanoid.params import RobotTruthParams

    _, servo, _ = plant_servo_noise(config)
    return RobotTruthParams(**{"servo": servo, **dict(config.emulator.plant)})


def leg_figures_of(config: Config) -> LegFigures:
    """Every figure as the emulator of `config` has it."""
    legs_robot(config)
    truth = _truth(config)
    n = len(config.joints)
    joints: dict[str, np.ndarray] = {}
    for key in JOINT_FIGURES + MODEL_FIGURES:
        if key in SERVO_FIGURES:
            joints[key] = np.array([getattr(truth.servo_params(i), key) for i in range(n)])
        elif key not in ZERO_FIGURES:
            joints[key] = np.array(truth.per_joint(key), dtype=float)
    motor, link = config.emulator.zero_errors(n)
    joints["motor_zero_error_rad"], joints["link_zero_error_rad"] = np.array(motor), np.array(link)
    models = [truth.gearbox_friction(i).law for i in range(n)]
    return LegFigures(joints, models, float(truth.mass_scale), tuple(config.joint_names))


def legs_twin_config(base: Config, figures: LegFigures) -> Config:
    """`base` with its [emulator] made to have these figures (every other key as recorded)."""
    legs_robot(base)
    plant = dict(base.emulator.plant)
    for key in JOINT_FIGURES + MODEL_FIGURES:
        if key not in ZERO_FIGURES:
            plant[key] = [float(v) for v in figures.joints[key]]
    plant["gearbox_friction_model"] = [m.value for m in figures.models]
    plant["mass_scale"] = float(figures.mass_scale)
    return base.changed(
        "emulator",
        plant=plant,
        motor_zero_error_rad=[float(v) for v in figures.joints["motor_zero_error_rad"]],
        link_zero_error_rad=[float(v) for v in figures.joints["link_zero_error_rad"]],
    )
