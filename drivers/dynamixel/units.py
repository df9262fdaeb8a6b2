"""Device units of a Dynamixel Pro <-> SI, one function per quantity.

Every conversion between the actuator's integers and SI happens here and nowhere else in the
driver. Per joint, two configuration values are applied here too:

- ``direction`` (+1 or -1): the sign between the device's positive sense and the joint's;
- ``offset_rad``: the *device* angle (rad, device frame) at which the joint angle is zero.

    device_angle_rad = offset_rad + direction * joint_angle_rad
    joint_angle_rad  = direction * (device_angle_rad - offset_rad)

Velocity, current and torque are only signed by ``direction`` (an offset has no meaning there).

Each model's figures come from its e-Manual page (drivers/dynamixel/models.py says which item
of the page): `units_of(model)`. A chain of several models converts with `ChainUnits`, the
same factors as arrays, one entry per joint (each its model's), so the functions below convert
a mixed chain in one call.

The functions accept scalars or numpy arrays (direction and offset broadcast per joint).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from drivers.dynamixel.models import ACTUATOR_MODELS, ActuatorModel

ArrayLike = npt.ArrayLike
FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


@dataclass(frozen=True)
class DeviceUnits:
    """The scale factors of one actuator model's control-table units.

    pulses_per_rev: Present/Goal Position counts per output revolution.
    position_limit_pulses: the largest |position| the device accepts in position mode.
    velocity_unit_rpm: output rpm per Present/Goal Velocity unit.
    current_unit_a: amperes per Present Current / Goal Torque / Torque Limit unit.
    torque_constant_nm_per_a: output torque per ampere, used only for a torque *estimate*.
    """

    pulses_per_rev: int
    position_limit_pulses: int
    velocity_unit_rpm: float
    current_unit_a: float
    torque_constant_nm_per_a: float

    @property
    def rad_per_pulse(self) -> float:
        return 2.0 * math.pi / self.pulses_per_rev

    @property
    def rad_s_per_velocity_unit(self) -> float:
        return self.velocity_unit_rpm * 2.0 * math.pi / 60.0


def units_of(model: ActuatorModel) -> DeviceUnits:
    """A model's units from its row of drivers/dynamixel/models.py.

    The torque constant is an ESTIMATE: the spec table's continuous torque over continuous
    current ("calculated from core motor spec"; 44.7 N m / 9.3 A = 4.806 N m/A on the
    H54-200-S500-R). Friction and the gear's efficiency make the real ratio load dependent;
    ROBOTIS-Framework uses a different figure for the H54-200 (6.8 N m/A, unverified). Use it for
    plots and sanity checks, not as a torque sensor."""
    return DeviceUnits(
        pulses_per_rev=model.pulses_per_rev,
        position_limit_pulses=model.position_limit_pulses,
        velocity_unit_rpm=model.velocity_unit_rpm,
        current_unit_a=model.current_unit_a,
        torque_constant_nm_per_a=model.continuous_torque_nm / model.continuous_current_a,
    )


# The H54-200-S500-R (model 54024): 501,923 pulse/rev, +-250,961 in position mode, 0.00199234
# rev/min and 16.11328 mA per unit.
H54_200_S500_R_UNITS = units_of(ACTUATOR_MODELS[54024])


@dataclass(frozen=True)
class ChainUnits:
    """The factors of `DeviceUnits` for a chain, one entry per joint (each its model's): what
    the conversions below take in place of one model's units."""

    rad_per_pulse: FloatArray
    rad_s_per_velocity_unit: FloatArray
    current_unit_a: FloatArray
    torque_constant_nm_per_a: FloatArray

    @classmethod
    def of(cls, per_joint: tuple[DeviceUnits, ...]) -> ChainUnits:
        def column(name: str) -> FloatArray:
            return np.array([getattr(units, name) for units in per_joint], dtype=np.float64)

        return cls(
            rad_per_pulse=column("rad_per_pulse"),
            rad_s_per_velocity_unit=column("rad_s_per_velocity_unit"),
            current_unit_a=column("current_unit_a"),
            torque_constant_nm_per_a=column("torque_constant_nm_per_a"),
        )


# One model's units, or a chain's (per joint): what the array conversions accept.
Units = DeviceUnits | ChainUnits


def to_signed(raw_value: int, size_bytes: int) -> int:
    """Two's-complement decoding of an unsigned SDK value (getData / readNByteTxRx).

    The SDK returns every value unsigned: -7 in an int32 item reads as 4294967289.
    """
    if size_bytes not in (1, 2, 4):
        raise ValueError(f"item size must be 1, 2 or 4 bytes, got {size_bytes}")
    bits = 8 * size_bytes
    raw_value &= (1 << bits) - 1
    return raw_value - (1 << bits) if raw_value >= 1 << (bits - 1) else raw_value


def position_to_rad(
    pulses: ArrayLike, units: Units, direction: ArrayLike = 1, offset_rad: ArrayLike = 0.0
) -> FloatArray:
    """Present Position pulses (signed) -> joint angle [rad]."""
    device_rad = np.asarray(pulses, dtype=np.float64) * units.rad_per_pulse
    return np.asarray(direction) * (device_rad - np.asarray(offset_rad))


def rad_to_position(
    angle_rad: ArrayLike, units: Units, direction: ArrayLike = 1, offset_rad: ArrayLike = 0.0
) -> IntArray:
    """Joint angle [rad] -> Goal Position pulses (nearest pulse, signed int64).

    No range check here: the chain checks goals against the joint limits before converting.
    """
    device_rad = np.asarray(offset_rad) + np.asarray(direction) * np.asarray(
        angle_rad, dtype=np.float64
    )
    return np.rint(device_rad / units.rad_per_pulse).astype(np.int64)


def velocity_to_rad_s(raw: ArrayLike, units: Units, direction: ArrayLike = 1) -> FloatArray:
    """Present Velocity units (signed; 0.00199234 rpm on the H54-200) -> joint velocity [rad/s]."""
    return np.asarray(direction) * (
        np.asarray(raw, dtype=np.float64) * units.rad_s_per_velocity_unit
    )


def rad_s_to_velocity(
    velocity_rad_s: ArrayLike, units: Units, direction: ArrayLike = 1
) -> IntArray:
    """Joint velocity [rad/s] -> Goal Velocity units (nearest unit, signed int64)."""
    device_rad_s = np.asarray(direction) * np.asarray(velocity_rad_s, dtype=np.float64)
    return np.rint(device_rad_s / units.rad_s_per_velocity_unit).astype(np.int64)


def current_to_a(raw: ArrayLike, units: Units, direction: ArrayLike = 1) -> FloatArray:
    """Present Current units (signed; 16.11328 mA on the H54-200) -> joint-frame current [A]."""
    return np.asarray(direction) * (np.asarray(raw, dtype=np.float64) * units.current_unit_a)


def current_limit_a_to_raw(current_a: float, units: DeviceUnits) -> int:
    """A current magnitude [A] (Torque Limit, Goal Torque cap) -> device units (nearest unit)."""
    if not math.isfinite(current_a) or current_a < 0.0:
        raise ValueError(f"a current limit must be a finite value >= 0 A, got {current_a!r}")
    return round(current_a / units.current_unit_a)


def current_limit_raw_to_a(raw: int, units: DeviceUnits) -> float:
    """Torque Limit / Goal Torque device units -> current magnitude [A]."""
    return raw * units.current_unit_a


def current_a_to_torque_estimate_nm(current_a: ArrayLike, units: Units) -> FloatArray:
    """Motor current [A] -> ESTIMATED output torque [N m] via the spec torque constant.

    Only an estimate: see `DeviceUnits.torque_constant_nm_per_a`. The sign follows the current
    (already in the joint frame when it comes from `current_to_a`).
    """
    return np.asarray(current_a, dtype=np.float64) * units.torque_constant_nm_per_a


def return_delay_us_to_raw(return_delay_us: int) -> int:
    """Return Delay Time [us] -> item 9 value (unit 2 us, 0..254; the same item on every model)."""
    if return_delay_us % 2 or not 0 <= return_delay_us <= 508:
        raise ValueError(
            f"return delay time must be an even number of microseconds in 0..508 "
            f"(item 9 counts 2 us steps), got {return_delay_us}"
        )
    return return_delay_us // 2


def input_voltage_to_v(raw: ArrayLike) -> FloatArray:
    """Present Input Voltage (unit 0.1 V) -> volts."""
    return np.asarray(raw, dtype=np.float64) * 0.1
