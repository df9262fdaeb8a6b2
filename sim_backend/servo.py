"""The DYNAMIXEL PRO's own position servo and overload protection, as its firmware would run them
(written for the H54-200-S500-R; every other model of the family runs the same law on its own
table, units and figures: `sim_backend.servo_models`).

The e-Manual documents the loop structure (Position P Gain 594 -> Velocity P/I Gain 588/586 ->
current, capped by Goal Torque 604 or Torque Limit 30, speed capped by Goal Velocity 600 or
Velocity Limit 32) but not the gains' physical units. We model the cascade in SI and scale each
gain linearly with its register, the register's factory default mapping to the SI default below:

    velocity command  w* = Kpp (theta_goal - theta_m), clipped to the speed cap
    motor torque      tau = kv (w* - dtheta_m) + kv/Ti * integral(w* - dtheta_m), clipped to the
                      current cap times the torque constant (anti-windup: no integration while
                      clipped)

Why these defaults (assumptions, documented in `H54ServoParams`):
- Kpp = 10 1/s: Kim et al. identified the stock actuator as a first-order lag with Kp = 10 1/s;
  with a fast inner velocity loop the cascade's position response is that lag.
- kv: the firmware tunes its velocity loop for the bare motor (the factory cannot know the
  load): a 50 Hz velocity bandwidth on the reflected rotor inertia. With Kpp this gives a static
  servo stiffness Kpp * kv = 785 N m/rad at the output.
- Ti: the stock velocity I gain is weak: its register (14) against the P gain (399) is ~30 times
  weaker than the X series' defaults; with the X series' gain scaling (KVP = reg/128,
  KVI = reg/65536) and a 1 kHz velocity loop it is Ti = 14.6 s. The paper's contact experiment
  corroborates a weak integral: its DOB stayed compliant, which needs the servo's finite static
  stiffness (the DOB senses a load only through the servo's position lag). Strong integral
  action would wind the lag out and defeat the DOB (`hil` reports this sensitivity).
Because of the velocity loop, the friction and the limits, the plant differs from the paper's
nominal first-order model as real hardware does.

Overload (Hardware Error Status bit 5): ROBOTIS does not publish the threshold. Our model, as the
brief suggests: an overload timer runs while |current| >= `overload_current_fraction` of the active
current cap and runs back down (at the same rate) below it; at `overload_trip_time_s` the firmware
raises the Overload bit, which with the default Shutdown mask clears Torque Enable, engages the
dynamic brake and sets the Alert bit until REBOOT (e-Manual, "Shutdown").

Torque off (Torque Enable 0, or after the shutdown): no motor torque, the velocity-loop integral
and the overload timer reset, the dynamic brake damps the motor side
(`dynamic_brake_damping_nms_per_rad`) until torque comes back. The Present* items report the
state after each physics step: Present Position (minus Homing Offset) and Present Velocity in
the device frame (the actuator's mounting applied), Present Current = motor torque / torque
constant plus its noise, Moving when |velocity| exceeds Moving Threshold.

The law runs for all actuators of a plant at once in `sim_backend.servo_bank.H54FirmwareBank`;
`sim_backend.firmware.H54Firmware` is one actuator's view of it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple, Protocol

from sim_backend.dynamixel.models import BY_NAME, DEFAULT_MODEL

if TYPE_CHECKING:
    from sim_backend.dynamixel.control_table import DeviceModel

OVERLOAD_BIT = 0x20

# Control-table units of the H54-200-S500-R, the testbed's and the humanoid's actuator (every
# model's: sim_backend.dynamixel.models; the drivers convert on their own side of the wire).
_H54_UNITS = BY_NAME[DEFAULT_MODEL].units
PULSES_PER_REV = _H54_UNITS.pulses_per_rev
RAD_PER_PULSE = _H54_UNITS.rad_per_pulse
RPM_PER_VELOCITY_UNIT = _H54_UNITS.velocity_unit_rpm
RAD_S_PER_VELOCITY_UNIT = _H54_UNITS.rad_s_per_velocity_unit
AMPERE_PER_CURRENT_UNIT = _H54_UNITS.ampere_per_current_unit  # 16.11328 mA
# Operating Mode values, the same on every model (PRO+ adds 16, PWM: run as current mode)
POSITION_MODE, EXTENDED_POSITION_MODE, VELOCITY_MODE, TORQUE_MODE = 3, 4, 1, 0


class ControlTable(Protocol):
    """The firmware's view of its control table (sim_backend.dynamixel.DynamixelProDevice
    provides it); `model` says which items hold the limits and in which units.

    `revision` changes whenever anything but the firmware's own measurements is written: the
    firmware decodes its registers again only then (it runs every physics step, 12 times over on
    the humanoid). `set_measurements` writes the Present* items in one go. A table may also
    offer `attach_measurement_source(fn)`: it then calls `fn()` before any read that may cover
    the Present* items, and the firmware writes them only then (H54Device does); a count
    `goal_position_writes` of the writes that were Goal Position alone, so that the firmware
    decodes only the goal after the host's every-tick write; and `add_write_counter(counter)`:
    the table steps a `WriteCounter` shared by the tables of a firmware bank with its
    `revision`, so that the bank sees with one comparison per physics step that none changed."""

    @property
    def model(self) -> DeviceModel: ...

    def item(self, name: str) -> int: ...

    def set_item(self, name: str, value: int) -> None: ...

    def raise_hardware_error(self, bits: int) -> None: ...

    @property
    def torque_enabled(self) -> bool: ...

    @property
    def revision(self) -> int: ...

    def set_measurements(self, measurements: Measurements) -> None: ...


class WriteCounter:
    """Counts the writes to the control tables it was added to (see `ControlTable`)."""

    def __init__(self) -> None:
        self.count = 0


class Measurements(NamedTuple):
    """The Present* items the firmware writes when they are read [device units] (a tuple: one
    per device per tick, made cheaply)."""

    moving: int
    position_pulses: int
    velocity_units: int
    current_units: int
    input_voltage_decivolts: int
    temperature_c: int


@dataclass(frozen=True)
class Registers:
    """The firmware's inputs decoded from the control table (SI), valid for one revision
    (Goal Position apart: `goal_angle_rad`, decoded alone when only it was written)."""

    position_gain_per_s: float
    velocity_gain_nms_per_rad: float
    integral_rate_nm_per_rad: float
    current_cap_a: float
    speed_cap_rad_s: float
    goal_velocity_rad_s: float
    goal_torque_a: float
    operating_mode: int
    homing_offset_pulses: int
    moving_threshold_rad_s: float


@dataclass(frozen=True)
class H54ServoParams:
    """SI figures of the emulated firmware. Register defaults map onto these values."""

    position_gain_per_s: float = 10.0  # Kim et al. Sec. IV-A (nominal Kp); register 594 = 32
    velocity_gain_nms_per_rad: float = 78.5  # 2 pi 50 Hz x 0.25 kg m^2; register 588 = 399
    velocity_integral_time_s: float = 15.0  # weak integral action; register 586 = 14
    torque_constant_nm_per_a: float = 44.7 / 9.3  # continuous torque / current (e-Manual spec)
    dynamic_brake_damping_nms_per_rad: float = 40.0  # shorted windings: Kt^2 / R, R ~ 0.6 ohm
    # Measurement noise of the Present* items (zero-mean Gaussian before rounding, seeded from the
    # emulator's seed; 0: off). ROBOTIS publish no figure for either.
    # Present Current: the coil current, which "can change very quickly due to the nature of the
    # controller" (ROBOTIS, DynamixelSDK issue #433); users see X-series readings at standstill
    # scatter over ~10 LSB of 2.69 mA (DynamixelSDK issues #264, #442). 20 mA rms is 1.2 LSB
    # of the H54's 16.1 mA.
    current_noise_a: float = 0.02
    # Present Velocity: the firmware differentiates its 501,923-pulse encoder; differenced over
    # the assumed 1 ms velocity-loop period, one pulse's quantisation gives an rms of
    # q / (T sqrt 6) = 1.2518e-5 rad / (1e-3 s x 2.449) = 5.1e-3 rad/s (24.5 units of
    # 0.00199234 rpm).
    velocity_noise_rad_s: float = 5.1e-3
    overload_current_fraction: float = 0.9
    overload_trip_time_s: float = 1.5
    temperature_c: float = 35.0
    input_voltage_v: float = 24.0
    default_position_gain_register: int = 32
    default_velocity_p_gain_register: int = 399
    default_velocity_i_gain_register: int = 14

    def __post_init__(self) -> None:
        for name in (
            "position_gain_per_s",
            "velocity_gain_nms_per_rad",
            "torque_constant_nm_per_a",
            "overload_trip_time_s",
        ):
            if not getattr(self, name) > 0:
                raise ValueError(f"servo parameter {name} must be > 0, got {getattr(self, name)}")
        if not 0 < self.overload_current_fraction <= 1:
            raise ValueError("overload_current_fraction must be in (0, 1]")
        for name in ("current_noise_a", "velocity_noise_rad_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"servo parameter {name} must be a finite rms >= 0, got {value}")

    def cascade_at(
        self, position_p_gain: int, velocity_p_gain: int, velocity_i_gain: int
    ) -> ServoCascade:
        """The cascade's SI gains at these register values (594, 588, 586): each gain scales
        linearly with its register, the register's default mapping to this object's figure.
        ASSUMED: ROBOTIS do not publish how a gain register maps to a gain in SI (the e-Manual
        gives the registers' ranges and initial values only). So DYROS-JET's lab registers, 96 /
        500 / 0 (hil/data/dyros_jet_lab.toml), are Kpp 30 1/s, kv 98.4 N m s/rad, no integral."""
        position = self.position_gain_per_s * position_p_gain / self.default_position_gain_register
        velocity = (
            self.velocity_gain_nms_per_rad * velocity_p_gain / self.default_velocity_p_gain_register
        )
        # kv / Ti in N m per rad of integrated speed error, scaled by the I register
        integral_rate = (
            self.velocity_gain_nms_per_rad
            / self.velocity_integral_time_s
            * velocity_i_gain
            / self.default_velocity_i_gain_register
        )
        return ServoCascade(position, velocity, integral_rate)


@dataclass(frozen=True)
class ServoCascade:
    """The firmware's position P -> velocity PI gains in SI at some register values."""

    position_gain_per_s: float  # Kpp
    velocity_gain_nms_per_rad: float  # kv
    integral_rate_nm_per_rad: float  # kv / Ti

    @property
    def velocity_integral_time_s(self) -> float:
        """Ti (inf with the I gain at 0)."""
        rate = self.integral_rate_nm_per_rad
        return self.velocity_gain_nms_per_rad / rate if rate > 0 else math.inf

    @property
    def static_stiffness_nm_per_rad(self) -> float:
        """Kpp kv: the torque per radian of position lag at rest before the integral grows."""
        return self.position_gain_per_s * self.velocity_gain_nms_per_rad


@dataclass
class ServoOutput:
    """What the firmware asks of the motor this physics step."""

    torque_on: bool
    velocity_command_rad_s: float  # the implicit velocity-loop input (includes the I term)
    torque_limit_nm: float


def goal_angle_rad(
    goal_position_pulses: int, homing_offset_pulses: int, rad_per_pulse: float = RAD_PER_PULSE
) -> float:
    """Goal Position in the device frame [rad]: the Homing Offset added, as Present Position
    subtracts it."""
    return (goal_position_pulses + homing_offset_pulses) * rad_per_pulse


def decode_registers(table: ControlTable, params: H54ServoParams) -> Registers:
    """The firmware's inputs in SI from its control table (each gain scaled linearly with its
    register, the factory default register mapping to the SI default of `params`), in the
    model's units and from its items (PRO: Goal Torque caps the current in every mode and Goal
    Velocity the speed; PRO+: Current Limit caps it, Goal Current is the current mode's goal and
    Profile Velocity caps the speed)."""
    p, item = params, table.item
    names, units = table.model.firmware_items, table.model.units
    ampere, rad_s = units.ampere_per_current_unit, units.rad_s_per_velocity_unit
    goal_torque, torque_limit = item(names.goal_current), item(names.current_limit)
    current_units = (
        abs(goal_torque)
        if names.goal_current_caps_every_mode and 0 < abs(goal_torque) <= torque_limit
        else torque_limit
    )
    speed_cap, velocity_limit = item(names.speed_cap), item("Velocity Limit")
    speed_units = abs(speed_cap) if 0 < abs(speed_cap) <= velocity_limit else velocity_limit
    goal_velocity = item("Goal Velocity")
    homing_offset = item("Homing Offset")
    cascade = p.cascade_at(
        item("Position P Gain"), item("Velocity P Gain"), item("Velocity I Gain")
    )
    return Registers(
        position_gain_per_s=cascade.position_gain_per_s,
        velocity_gain_nms_per_rad=cascade.velocity_gain_nms_per_rad,
        integral_rate_nm_per_rad=cascade.integral_rate_nm_per_rad,
        current_cap_a=current_units * ampere,
        speed_cap_rad_s=speed_units * rad_s,
        goal_velocity_rad_s=goal_velocity * rad_s,
        goal_torque_a=goal_torque * ampere,
        operating_mode=item("Operating Mode"),
        homing_offset_pulses=homing_offset,
        moving_threshold_rad_s=item("Moving Threshold") * rad_s,
    )
