"""The abstract joint bus: what the loop sees of a set of flexible joints, in SI units.

Modelled on python-can's `BusABC`: one small abstract class, implementations chosen by
configuration, the same loop code for the real testbed and the emulated one.
"""

from __future__ import annotations

import abc
import enum
from dataclasses import dataclass, field

import numpy as np


class HardwareError(enum.IntFlag):
    """Bits of the Dynamixel Pro Hardware Error Status (address 892) and Shutdown (48) items.

    Source: ROBOTIS e-Manual, H54-200-S500-R, "Shutdown" (bits 7 and 6 are unused).
    """

    INPUT_VOLTAGE = 0x01
    MOTOR_HALL_SENSOR = 0x02
    OVERHEATING = 0x04
    MOTOR_ENCODER = 0x08
    ELECTRICAL_SHOCK = 0x10
    OVERLOAD = 0x20

    @classmethod
    def describe(cls, bits: int) -> str:
        """'OVERLOAD|OVERHEATING' for the set bits, 'none' for 0."""
        names = [flag.name for flag in cls if bits & flag and flag.name]
        return "|".join(names) if names else "none"


class BusError(RuntimeError):
    """A joint bus could not be opened, read or written (message says which device and why)."""


@dataclass
class JointSample:
    """One reading of every joint, SI units, arrays of length n_joints.

    A value that could not be read this tick is NaN and its `*_valid` flag is False: the bus
    never reports a silent zero.
    """

    timestamp_s: float
    motor_angle_rad: np.ndarray
    link_angle_rad: np.ndarray
    motor_velocity_rad_s: np.ndarray
    motor_current_a: np.ndarray
    hardware_error: np.ndarray  # uint8 per joint, HardwareError bits (0 = healthy)
    torque_enabled: np.ndarray  # bool per joint, as read back from the device
    motor_valid: np.ndarray  # bool per joint: the actuator answered this tick
    link_valid: np.ndarray  # bool per joint: a fresh link-encoder value arrived this tick
    link_age_s: np.ndarray  # seconds since the last fresh link value (0 when fresh)
    bus_errors: list[str] = field(default_factory=list)  # what went wrong this tick, if anything
    notes: list[str] = field(default_factory=list)  # bus events worth logging (boot-up, EMCY)
    extra: dict[str, float] = field(default_factory=dict)  # e.g. contact force from a sensor

    @classmethod
    def empty(cls, n_joints: int, timestamp_s: float = 0.0) -> JointSample:
        nan = np.full(n_joints, np.nan)
        return cls(
            timestamp_s=timestamp_s,
            motor_angle_rad=nan.copy(),
            link_angle_rad=nan.copy(),
            motor_velocity_rad_s=nan.copy(),
            motor_current_a=nan.copy(),
            hardware_error=np.zeros(n_joints, dtype=np.uint8),
            torque_enabled=np.zeros(n_joints, dtype=bool),
            motor_valid=np.zeros(n_joints, dtype=bool),
            link_valid=np.zeros(n_joints, dtype=bool),
            link_age_s=np.full(n_joints, np.inf),
        )

    @property
    def deflection_rad(self) -> np.ndarray:
        """Link minus motor angle: positive when the load leads the motor."""
        return self.link_angle_rad - self.motor_angle_rad


class JointBus(abc.ABC):
    """A set of n flexible joints: read state, write goal motor angles.

    Lifecycle: `open()` checks and configures the devices without enabling torque; `enable()`
    turns torque on; each tick calls `read()` then `write()`; `disable()` turns torque off;
    `close()` releases the ports (it does not change the torque state: the caller decides).
    Use it as a context manager to guarantee `close()`.
    """

    joint_names: tuple[str, ...]

    @property
    def n_joints(self) -> int:
        return len(self.joint_names)

    @abc.abstractmethod
    def open(self) -> None:
        """Connect, identify every device (refuse a wrong model) and configure it. No torque."""

    @abc.abstractmethod
    def read(self) -> JointSample:
        """Sample every joint once (one bus transaction per device family)."""

    @abc.abstractmethod
    def write(self, goal_motor_angle_rad: np.ndarray) -> None:
        """Send one goal motor angle per joint (one bus transaction)."""

    @abc.abstractmethod
    def enable(self) -> None:
        """Torque on for every joint."""

    @abc.abstractmethod
    def disable(self) -> None:
        """Torque off for every joint (best effort on every joint even if one fails)."""

    @abc.abstractmethod
    def reboot(self, joints: list[int] | None = None) -> dict[int, int]:
        """Reboot the actuators (all, or these joint indices); clears latched hardware errors.

        Returns the Hardware Error Status bits each device reports after the reboot.
        """

    @abc.abstractmethod
    def close(self) -> None:
        """Release ports and threads. Safe to call twice."""

    def current_limits_a(self) -> np.ndarray:
        """Each actuator's current cap [A] as the device reports it (after open()); NaN where
        the bus cannot tell. The supervisor's overload guard compares the current against it."""
        return np.full(self.n_joints, np.nan)

    def __enter__(self) -> JointBus:
        self.open()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()
