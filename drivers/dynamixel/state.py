"""What a chain reports: per-tick state, single hardware-error reads, what open() found."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from drivers.dynamixel.hardware_error import HardwareError


@dataclass
class DynamixelState:
    """One sync read of the chain, SI units, arrays in chain order (config.joints).

    Where `valid` is False the floats are NaN, `hardware_error` is 0 and `torque_enabled` and
    `alert` are False: that device's reply did not arrive (or was rejected) in this read, and
    `errors` says why. Values are never carried over from an earlier read.

    position_rad, velocity_rad_s, current_a: joint frame (direction and offset applied).
    torque_estimate_nm: current x the spec torque constant, an ESTIMATE (see units.py).
    hardware_error: Hardware Error Status (892) bits, `drivers.dynamixel.HardwareError`.
    torque_enabled: Torque Enable (562) as read; a shutdown clears it.
    alert: the Alert bit (0x80) of the device's status packet for this read.
    """

    dxl_ids: tuple[int, ...]
    position_rad: np.ndarray
    velocity_rad_s: np.ndarray
    current_a: np.ndarray
    torque_estimate_nm: np.ndarray
    input_voltage_v: np.ndarray
    temperature_c: np.ndarray
    hardware_error: np.ndarray  # uint8
    torque_enabled: np.ndarray  # bool
    alert: np.ndarray  # bool
    valid: np.ndarray  # bool
    errors: list[str] = field(default_factory=list)
    invalid_reasons: dict[int, str] = field(default_factory=dict)  # by ID: why not valid

    @property
    def all_valid(self) -> bool:
        return bool(self.valid.all())


@dataclass(frozen=True)
class HardwareErrorStatus:
    """A single READ of Hardware Error Status (892) and the Alert bit of that reply."""

    dxl_id: int
    bits: int
    alert: bool

    def describe(self) -> str:
        return HardwareError.describe(self.bits)


@dataclass(frozen=True)
class DeviceInfo:
    """What `open()` found on a device and what it changed."""

    dxl_id: int
    model_number: int
    firmware_version: int
    shutdown_mask: int  # Shutdown (48): which hardware errors turn torque off
    hardware_error: int  # Hardware Error Status at open
    torque_enabled: bool  # after open() (open never turns torque on)
    eeprom_changes: tuple[str, ...]  # e.g. "Operating Mode 4 -> 3" (read-only: still to do)
    current_limit_a: float  # Torque Limit (PRO+: Current Limit) after open(), in A: the cap
    model_name: str = ""  # the model it answered PING as (e-Manual name)
