"""Each model's servo and overload figures: the H54-200-S500-R's (`H54ServoParams`, servo.py)
carried over to the rest of the family, each figure from the model's e-Manual page or by a
named assumption.

ROBOTIS publish, per model, the specification table (continuous torque and current "calculated
from the core motor's specification", gear ratio, resolution) and the gain registers' initial
values (where the page prints them), not the loop's physical gains, the rotor inertia, the
winding resistance or the overload threshold. So, for a model M against the H54-200-S500-R:

    torque_constant_nm_per_a        M's continuous torque / continuous current (e-Manual spec)
    default_*_gain_register         M's gain registers' initial values (models.Gains; where the
                                    page prints "-", the assumption models.py names)
    velocity_noise_rad_s            one pulse of M's encoder differenced over the assumed 1 ms
                                    velocity-loop period: (2 pi / pulses_per_rev) / (1 ms sqrt 6)
    velocity_gain_nms_per_rad       ASSUMED: the H54-200's 78.5 N m s/rad scaled by M's continuous
                                    torque over the H54-200's 44.7 N m (the factory tunes the loop
                                    on the bare motor; its reflected inertia is not published and
                                    is taken to grow with the motor's size)
    dynamic_brake_damping_nms_per_rad  ASSUMED: scaled the same way (Kt^2 / R of the motor)
    current_noise_a                 ASSUMED: scaled by M's continuous current over 9.3 A (the
                                    same relative scatter of the coil current)
    position_gain_per_s, velocity_integral_time_s, overload_current_fraction,
    overload_trip_time_s, temperature_c, input_voltage_v
                                    the H54-200-S500-R's (its assumptions, servo.py: ROBOTIS
                                    publish none of them for any model)

The H54-200-S500-R itself keeps the figures it is given, unchanged: the testbed's and
DYROS-JET's emulation are what they were.
"""

from __future__ import annotations

import dataclasses
import math

from sim_backend.dynamixel.models import DEFAULT_MODEL, ModelFigures, figures_of
from sim_backend.servo import H54ServoParams

VELOCITY_LOOP_PERIOD_S = 1e-3  # assumed (servo.py: the H54-200's velocity noise figure)


def velocity_quantisation_noise_rad_s(figures: ModelFigures) -> float:
    """One encoder pulse differenced over a velocity-loop period, rms: q / (T sqrt 6)."""
    pulse_rad = 2.0 * math.pi / figures.pulses_per_rev
    return pulse_rad / (VELOCITY_LOOP_PERIOD_S * math.sqrt(6.0))


def servo_params_for(model: str, base: H54ServoParams | None = None) -> H54ServoParams:
    """The servo figures of `model` (e-Manual name), derived from `base` (the H54-200-S500-R's,
    default `H54ServoParams()`) as the module docstring says; `base` itself for the
    H54-200-S500-R. ValueError for a model the emulator does not serve."""
    base = H54ServoParams() if base is None else base
    figures = figures_of(model)
    if figures.name == DEFAULT_MODEL:
        return base
    h54 = figures_of(DEFAULT_MODEL)
    size = figures.continuous_torque_nm / h54.continuous_torque_nm
    return dataclasses.replace(
        base,
        torque_constant_nm_per_a=figures.continuous_torque_nm / figures.continuous_current_a,
        velocity_gain_nms_per_rad=base.velocity_gain_nms_per_rad * size,
        dynamic_brake_damping_nms_per_rad=base.dynamic_brake_damping_nms_per_rad * size,
        current_noise_a=base.current_noise_a
        * figures.continuous_current_a
        / h54.continuous_current_a,
        velocity_noise_rad_s=velocity_quantisation_noise_rad_s(figures),
        default_position_gain_register=figures.gains.position_p,
        default_velocity_p_gain_register=figures.gains.velocity_p,
        default_velocity_i_gain_register=figures.gains.velocity_i,
    )
