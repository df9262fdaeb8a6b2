"""Configuration of a Dynamixel chain: one port, its joints, and how to talk to them.

All quantities are SI at this interface; device units are derived from it in `units.py`.
The checks here run when the configuration is built, before any port is touched.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from drivers.dynamixel.control_table import DEFAULT_MODEL_NUMBER, ModelSpec, model_spec
from drivers.dynamixel.state_block import StateBlockLayout
from drivers.dynamixel.units import (
    ChainUnits,
    DeviceUnits,
    current_limit_a_to_raw,
    return_delay_us_to_raw,
)

MAX_DXL_ID = 252  # Protocol 2.0: IDs 0..252; 253..255 clash with the header / broadcast


@dataclass(frozen=True, kw_only=True)
class DynamixelJointConfig:
    """One actuator of the chain.

    model_number: its model (drivers/dynamixel/models.py); None: the chain's `model_number`.
        `open()` PINGs it and refuses a device of another model.
    direction: +1 or -1, the sign from the device's positive sense to the joint's.
    offset_rad: the device angle [rad, device frame] at which the joint angle is zero
        (joint = direction * (device - offset)).
    min_position_rad / max_position_rad: the joint's range; written to the device's Min/Max
        Position Limit (40/36) and enforced on every goal before it is sent.
    torque_limit_a: Torque Limit (30) as a current [A]; None leaves the device's value.
    position_p_gain / velocity_p_gain / velocity_i_gain: the servo's RAM gains (PRO 594, 588,
        586; PRO+ 532, 526, 524) in the device's own units (they have no SI meaning, 0..65,535
        on the PRO, 0..32,767 on PRO+); None leaves the device's value.
        RAM items return to their defaults on reboot, so the chain re-applies them.
    name: for messages and logs (defaults to "ID <dxl_id>").
    """

    dxl_id: int
    model_number: int | None = None
    direction: int = +1
    offset_rad: float = 0.0
    min_position_rad: float
    max_position_rad: float
    torque_limit_a: float | None = None
    position_p_gain: int | None = None
    velocity_p_gain: int | None = None
    velocity_i_gain: int | None = None
    name: str = ""

    def __post_init__(self) -> None:
        if not 0 <= self.dxl_id <= MAX_DXL_ID:
            raise ValueError(f"dxl_id must be in 0..{MAX_DXL_ID}, got {self.dxl_id}")
        if self.direction not in (1, -1):
            raise ValueError(f"{self.label}: direction must be +1 or -1, got {self.direction!r}")
        if not math.isfinite(self.offset_rad):
            raise ValueError(f"{self.label}: offset_rad must be finite, got {self.offset_rad!r}")
        if not (
            math.isfinite(self.min_position_rad)
            and math.isfinite(self.max_position_rad)
            and self.min_position_rad < self.max_position_rad
        ):
            raise ValueError(
                f"{self.label}: need finite min_position_rad < max_position_rad, got "
                f"{self.min_position_rad!r} .. {self.max_position_rad!r}"
            )
        if self.torque_limit_a is not None and not (
            math.isfinite(self.torque_limit_a) and self.torque_limit_a > 0.0
        ):
            raise ValueError(
                f"{self.label}: torque_limit_a must be a finite current > 0 A (or None to keep "
                f"the device's), got {self.torque_limit_a!r}"
            )
        for gain_name in ("position_p_gain", "velocity_p_gain", "velocity_i_gain"):
            gain = getattr(self, gain_name)
            if gain is not None and not (isinstance(gain, int) and 0 <= gain <= 65535):
                raise ValueError(
                    f"{self.label}: {gain_name} must be an integer in 0..65535 (device units, "
                    f"e-Manual items 586/588/594) or None, got {gain!r}"
                )
        if self.model_number is not None:
            model_spec(self.model_number)  # ValueError naming the supported models

    @property
    def label(self) -> str:
        return f"ID {self.dxl_id} ({self.name})" if self.name else f"ID {self.dxl_id}"

    def device_position_limits_pulses(self, units: DeviceUnits) -> tuple[int, int]:
        """(Min, Max) Position Limit in device pulses for this joint's range.

        Rounded outwards, so that every goal inside [min_position_rad, max_position_rad]
        (rounded to the nearest pulse) lies inside the device's limits too: a sync write has no
        reply, and a Data Limit error on it would go unseen.
        """
        ends = (
            (self.offset_rad + self.direction * self.min_position_rad) / units.rad_per_pulse,
            (self.offset_rad + self.direction * self.max_position_rad) / units.rad_per_pulse,
        )
        return math.floor(min(ends)), math.ceil(max(ends))

    def ram_gains(self) -> tuple[tuple[str, int], ...]:
        """(item name, value) of the configured RAM gains."""
        gains = (
            ("Position P Gain", self.position_p_gain),
            ("Velocity P Gain", self.velocity_p_gain),
            ("Velocity I Gain", self.velocity_i_gain),
        )
        return tuple((name, value) for name, value in gains if value is not None)


@dataclass(frozen=True, kw_only=True)
class DynamixelChainConfig:
    """A chain of actuators on one serial port (RS-485, Protocol 2.0), of one model or several.

    model_number: the joints' model where a joint names none (default the H54-200-S500-R).
    baudrate: bits per second; must be in both the SDK's whitelist and every model's table.
    return_delay_time_us: written to each device's Return Delay Time (9); 0 is what a fast loop
        wants (the default 500 us per device adds up in a sync read; DynamixelSDK issue #302).
    latency_timer_ms: the USB-serial adapter's latency, used in the reply timeout (see
        `port.LowLatencyPortHandler`); set the adapter to match (ROBOTIS advise 1 ms).
    timeout_margin_ms: the constant added to every reply timeout (the SDK uses 2 ms).
    reboot_timeout_s: how long `reboot()` waits for a device to answer ping again.
    indirect_first_index: first Indirect Address/Data entry (1-based) used for the state block;
        the block uses one entry per byte (15, see `state_block.py`) from there.
    """

    port: str
    baudrate: int
    joints: tuple[DynamixelJointConfig, ...]
    model_number: int = DEFAULT_MODEL_NUMBER
    return_delay_time_us: int = 0
    latency_timer_ms: float = 1.0
    timeout_margin_ms: float = 2.0
    reboot_timeout_s: float = 3.0
    indirect_first_index: int = 1

    def __post_init__(self) -> None:
        object.__setattr__(self, "joints", tuple(self.joints))
        if not self.joints:
            raise ValueError("a Dynamixel chain needs at least one joint")
        ids = [joint.dxl_id for joint in self.joints]
        duplicates = sorted({dxl_id for dxl_id in ids if ids.count(dxl_id) > 1})
        if duplicates:
            raise ValueError(f"Dynamixel IDs must be unique on one port; repeated: {duplicates}")
        model_spec(self.model_number)  # ValueError for an unsupported model
        for spec in {spec.model_number: spec for spec in self.specs}.values():
            if self.baudrate not in spec.baud_rates_bps.values():
                raise ValueError(
                    f"baudrate {self.baudrate} is not a rate the {spec.model_name} supports; "
                    f"its Baud Rate item offers {sorted(spec.baud_rates_bps.values())}"
                )
            StateBlockLayout(spec, self.indirect_first_index).check_fits()
        return_delay_us_to_raw(self.return_delay_time_us)  # raises with the reason
        for name in ("latency_timer_ms", "reboot_timeout_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be a finite value > 0, got {value!r}")
        if not (math.isfinite(self.timeout_margin_ms) and self.timeout_margin_ms >= 0.0):
            raise ValueError(f"timeout_margin_ms must be >= 0, got {self.timeout_margin_ms!r}")
        for joint, spec in zip(self.joints, self.specs, strict=True):
            _check_joint(joint, spec)

    @property
    def spec(self) -> ModelSpec:
        """The chain's default model (`model_number`); each joint's is in `specs`."""
        return model_spec(self.model_number)

    @property
    def specs(self) -> tuple[ModelSpec, ...]:
        """Each joint's model, in `joints` order."""
        return tuple(
            model_spec(self.model_number if j.model_number is None else j.model_number)
            for j in self.joints
        )

    @property
    def units(self) -> ChainUnits:
        """Each joint's units as arrays (the conversions of units.py take them)."""
        return ChainUnits.of(tuple(spec.units for spec in self.specs))

    @property
    def mixed(self) -> bool:
        """The joints are of more than one model."""
        return len({spec.model_number for spec in self.specs}) > 1

    @property
    def dxl_ids(self) -> tuple[int, ...]:
        return tuple(joint.dxl_id for joint in self.joints)


def _check_joint(joint: DynamixelJointConfig, spec: ModelSpec) -> None:
    """One joint's figures against its model: position range, current cap, gain registers."""
    limit = spec.units.position_limit_pulses
    low, high = joint.device_position_limits_pulses(spec.units)
    if low < -limit or high > limit:
        span = limit * spec.units.rad_per_pulse
        raise ValueError(
            f"{joint.label}: position range {joint.min_position_rad!r} .. "
            f"{joint.max_position_rad!r} rad maps to device pulses {low} .. {high} "
            f"(offset {joint.offset_rad!r} rad, direction {joint.direction:+d}), outside "
            f"the {spec.model_name}'s position-mode range +-{limit} pulses "
            f"(+-{span:.5f} rad)"
        )
    if joint.torque_limit_a is not None:
        raw = current_limit_a_to_raw(joint.torque_limit_a, spec.units)
        if not 1 <= raw <= spec.torque_limit_max_raw:
            max_a = spec.torque_limit_max_raw * spec.units.current_unit_a
            raise ValueError(
                f"{joint.label}: torque_limit_a={joint.torque_limit_a!r} A is outside the "
                f"{spec.model_name}'s {spec.item('Torque Limit').name} range "
                f"(0 < limit <= {max_a:.2f} A)"
            )
    for name, value in joint.ram_gains():
        if value > spec.gain_max_raw:
            raise ValueError(
                f"{joint.label}: {name} {value} is outside the {spec.model_name}'s range "
                f"0..{spec.gain_max_raw}"
            )
