"""The ranges of the emulated robot's figures that `[emulator] plant / servo / sensor_noise`
may override (the emulator's classes: sim_backend.plant.TestbedPlantParams,
sim_backend.humanoid.params.RobotTruthParams, sim_backend.fixed_base.params.
FixedBaseTruthParams, sim_backend.servo.H54ServoParams,
sim_backend.spec.SensorNoise), judged when the configuration is read.

The truth may differ from the controller's [model] on purpose (robustness runs, sweeps): its
ranges are those of the same figures in [model] (hil.config.figures), or, for what [model] has
no figure of, the physical reason beside it. A figure given per joint (the humanoid's twelve) is
judged element by element. A key without a range here is the emulator's to refuse (an unknown
key) or a word (a link's name, a friction cone).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from hil.config.figures import (
    Angle,
    CoulombFriction,
    Damping,
    IntegralTime,
    RotorInertia,
    ServoGain,
    Stiffness,
    VelocityGain,
    ViscousFriction,
)

Range = tuple[float, float, str]  # low, high (both included), why


def _of(figure: Any, why: str = "as in [model]") -> Range:
    """The range a `hil.config.figures` type declares."""
    low = high = None
    for constraint in figure.__metadata__[0].metadata:
        low = getattr(constraint, "ge", low)
        high = getattr(constraint, "le", high)
    assert low is not None and high is not None
    return float(low), float(high), why


REGISTER: Range = (0, 65535, "a 16-bit gain register of the H54 (e-Manual items 586/588/594)")
PHYSICS_STEP: Range = (1.0e-5, 2.0e-3, "MuJoCo's implicitfast step, measured stable up to 2 ms")
GRAVITY: Range = (0.0, 20.0, "from none to twice the Earth's")

PLANT: Mapping[str, Range] = {
    "gear_stiffness_nm_per_rad": _of(Stiffness),
    "gear_damping_nms_per_rad": _of(Damping),
    "motor_reflected_inertia_kg_m2": _of(RotorInertia),
    "gearbox_coulomb_friction_nm": _of(CoulombFriction),
    "gearbox_viscous_friction_nms_per_rad": _of(ViscousFriction),
    "gearbox_stribeck_friction_nm": _of(CoulombFriction, "as the Coulomb friction's in [model]"),
    "gearbox_stribeck_velocity_rad_s": (1.0e-4, 10.0, "a Stribeck speed within the H54's reach"),
    "gearbox_load_friction_ratio": (0.0, 0.5, "up to half the torque the gearbox transmits"),
    "link_length_m": (0.01, 3.0, "a link an H54 swings: 1 cm to 3 m"),
    "link_mass_kg": (0.01, 20.0, "a link an H54 swings: 10 g to 20 kg"),
    "load_mass_kg": (0.0, 20.0, "no load up to 20 kg (more than the H54 holds at 0.7 m)"),
    "load_radius_m": (0.001, 0.5, "a load of 1 mm to 0.5 m radius"),
    "gravity_m_s2": GRAVITY,
    "initial_link_angle_rad": _of(Angle, "within half a turn"),
    "physics_timestep_s": PHYSICS_STEP,
    # the humanoid's truth
    "mass_scale": (0.25, 4.0, "the robot's mass from a quarter to four times DYROS-JET's"),
    "com_offset_m": (-0.5, 0.5, "a centre-of-mass shift within the torso's half-metre"),
    "upper_body_angles_rad": _of(Angle, "within half a turn"),
    "position_gain_registers": REGISTER,
    # per joint, the same figures as [emulator] servo's (gearbox_friction_model is a word)
    "position_gain_per_s": _of(ServoGain),
    "velocity_gain_nms_per_rad": _of(VelocityGain),
    "velocity_integral_time_s": _of(IntegralTime),
    "contact.friction": (0.0, 10.0, "Coulomb friction from ice to glue"),
    "contact.time_constant_s": (2.0e-3, 1.0, "MuJoCo's solref: twice the 1 ms step at least"),
    "contact.damping_ratio": (0.1, 10.0, "MuJoCo's solref damping ratio"),
    "contact.friction_impedance_ratio": (1.0, 1.0e4, "MuJoCo's impratio (>= 1)"),
    # a fixed-base robot's truth (and mass_scale, com_offset_m above)
    "block_time_constant_s": (2.0e-3, 1.0, "MuJoCo's solref: twice the 1 ms step at least"),
    "block_damping_ratio": (0.1, 10.0, "MuJoCo's solref damping ratio"),
}
SERVO: Mapping[str, Range] = {
    "position_gain_per_s": _of(ServoGain),
    "velocity_gain_nms_per_rad": _of(VelocityGain),
    "velocity_integral_time_s": _of(IntegralTime),
    "torque_constant_nm_per_a": (0.1, 20.0, "the H54's 4.8 N m/A, within a factor of ~40"),
    "dynamic_brake_damping_nms_per_rad": (0.0, 1000.0, "shorted windings: Kt^2 / R (H54: 40)"),
    "current_noise_a": (0.0, 1.0, "Present Current's noise: up to 60 of its 16 mA units"),
    "velocity_noise_rad_s": (0.0, 1.0, "Present Velocity's noise: up to 1 rad/s rms"),
    "overload_current_fraction": (0.01, 1.0, "a share of the current limit"),
    "overload_trip_time_s": (0.01, 60.0, "an overload protection that acts within a minute"),
    "temperature_c": (-40.0, 150.0, "what the H54's sensor can read"),
    "input_voltage_v": (0.0, 60.0, "the H54's supply, 24 V nominal"),
    "default_position_gain_register": REGISTER,
    "default_velocity_p_gain_register": REGISTER,
    "default_velocity_i_gain_register": REGISTER,
}
SENSOR_NOISE: Mapping[str, Range] = {
    "link_encoder_counts_rms": (0.0, 1000.0, "up to 1000 counts rms (noisy_encoder: 50)"),
    "force_sensor_n_rms": (0.0, 100.0, "up to 100 N rms"),
}
RANGES: Mapping[str, Mapping[str, Range]] = {
    "plant": PLANT,
    "servo": SERVO,
    "sensor_noise": SENSOR_NOISE,
}


def check_overrides(part: str, values: Mapping[str, Any]) -> None:
    """Every number of `[emulator] part` within its range: ValueError naming the key."""
    _check(part, RANGES[part], values, "")


def _check(part: str, ranges: Mapping[str, Range], values: Mapping[str, Any], prefix: str) -> None:
    for key, value in values.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            if name in ranges:  # a table of angles by joint name
                for joint, item in value.items():
                    _judge(part, f"{name}.{joint}", item, ranges[name])
            else:
                _check(part, ranges, value, f"{name}.")
        elif name in ranges:
            items = value if isinstance(value, list | tuple) else [value]
            for index, item in enumerate(items):
                where = f"{name}[{index}]" if isinstance(value, list | tuple) else name
                _judge(part, where, item, ranges[name])


def _judge(part: str, where: str, value: Any, allowed: Range) -> None:
    low, high, why = allowed
    if isinstance(value, bool) or not isinstance(value, int | float):
        return  # a word, or a wrong type: the emulator's class says what it expects
    if not (math.isfinite(value) and low <= value <= high):
        raise ValueError(f"{part}.{where}: {value!r} is outside {low:g} .. {high:g} ({why})")
