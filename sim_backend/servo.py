"""The H54-200-S500-R's own position servo and overload protection, as its firmware would run them.

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
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

OVERLOAD_BIT = 0x20

# Control-table units of the H54-200-S500-R (e-Manual; also in drivers/, converted there for the
# host side - the emulator converts on its own side of the wire).
PULSES_PER_REV = 501_923
RAD_PER_PULSE = 2.0 * math.pi / PULSES_PER_REV
RPM_PER_VELOCITY_UNIT = 0.00199234
RAD_S_PER_VELOCITY_UNIT = RPM_PER_VELOCITY_UNIT * 2.0 * math.pi / 60.0
AMPERE_PER_CURRENT_UNIT = 33.0 / 2048.0  # 16.11328 mA
POSITION_MODE, EXTENDED_POSITION_MODE, VELOCITY_MODE, TORQUE_MODE = 3, 4, 1, 0


class ControlTable(Protocol):
    """The firmware's view of its control table (sim_backend.dynamixel.H54Device provides it).

    `revision` changes whenever anything but the firmware's own measurements is written: the
    firmware decodes its registers again only then (it runs every physics step, 12 times over on
    the humanoid). `set_measurements` writes the Present* items in one go."""

    def item(self, name: str) -> int: ...

    def set_item(self, name: str, value: int) -> None: ...

    def raise_hardware_error(self, bits: int) -> None: ...

    @property
    def torque_enabled(self) -> bool: ...

    @property
    def revision(self) -> int: ...

    def set_measurements(self, measurements: Measurements) -> None: ...


@dataclass(frozen=True)
class Measurements:
    """The Present* items the firmware writes after each physics step [device units]."""

    moving: int
    position_pulses: int
    velocity_units: int
    current_units: int
    input_voltage_decivolts: int
    temperature_c: int


@dataclass(frozen=True)
class _Registers:
    """The firmware's inputs decoded from the control table (SI), valid for one revision."""

    position_gain_per_s: float
    velocity_gain_nms_per_rad: float
    integral_rate_nm_per_rad: float
    current_cap_a: float
    speed_cap_rad_s: float
    goal_angle_rad: float
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
        linearly with its register, the register's default mapping to this object's figure."""
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


class H54Firmware:
    """Runs one actuator's servo and protection every physics step against its control table."""

    def __init__(self, table: ControlTable, params: H54ServoParams) -> None:
        self.table = table
        self.params = params
        self.integral_nm = 0.0
        self.overload_timer_s = 0.0
        self.last_current_a = 0.0
        self._registers_cache: tuple[int, _Registers] | None = None

    def on_reboot(self) -> None:
        self.integral_nm = 0.0
        self.overload_timer_s = 0.0

    # --- gains and goals from registers ----------------------------------------------------
    @property
    def registers(self) -> _Registers:
        """The control table's registers in SI, decoded again only after a write."""
        revision = self.table.revision
        cached = self._registers_cache
        if cached is None or cached[0] != revision:
            cached = (revision, self._decode_registers())
            self._registers_cache = cached
        return cached[1]

    def _decode_registers(self) -> _Registers:
        p, item = self.params, self.table.item
        goal_torque, torque_limit = item("Goal Torque"), item("Torque Limit")
        current_units = abs(goal_torque) if 0 < abs(goal_torque) <= torque_limit else torque_limit
        goal_velocity, velocity_limit = item("Goal Velocity"), item("Velocity Limit")
        speed_units = (
            abs(goal_velocity) if 0 < abs(goal_velocity) <= velocity_limit else velocity_limit
        )
        homing_offset = item("Homing Offset")
        cascade = p.cascade_at(
            item("Position P Gain"), item("Velocity P Gain"), item("Velocity I Gain")
        )
        return _Registers(
            position_gain_per_s=cascade.position_gain_per_s,
            velocity_gain_nms_per_rad=cascade.velocity_gain_nms_per_rad,
            integral_rate_nm_per_rad=cascade.integral_rate_nm_per_rad,
            current_cap_a=current_units * AMPERE_PER_CURRENT_UNIT,
            speed_cap_rad_s=speed_units * RAD_S_PER_VELOCITY_UNIT,
            goal_angle_rad=(item("Goal Position") + homing_offset) * RAD_PER_PULSE,
            goal_velocity_rad_s=goal_velocity * RAD_S_PER_VELOCITY_UNIT,
            goal_torque_a=goal_torque * AMPERE_PER_CURRENT_UNIT,
            operating_mode=item("Operating Mode"),
            homing_offset_pulses=homing_offset,
            moving_threshold_rad_s=item("Moving Threshold") * RAD_S_PER_VELOCITY_UNIT,
        )

    def _position_gain(self) -> float:
        return self.registers.position_gain_per_s

    def velocity_gain(self) -> float:
        return self.registers.velocity_gain_nms_per_rad

    def current_cap_a(self) -> float:
        return self.registers.current_cap_a

    def speed_cap_rad_s(self) -> float:
        return self.registers.speed_cap_rad_s

    def goal_angle_rad(self) -> float:
        return self.registers.goal_angle_rad

    # --- one physics step --------------------------------------------------------------------
    def compute(
        self, motor_angle_rad: float, motor_velocity_rad_s: float, dt_s: float
    ) -> ServoOutput:
        """The velocity-loop input and torque cap for this step (position modes only)."""
        if not self.table.torque_enabled:
            self.integral_nm = 0.0
            return ServoOutput(False, 0.0, 0.0)
        registers = self.registers
        torque_cap = registers.current_cap_a * self.params.torque_constant_nm_per_a
        kv = registers.velocity_gain_nms_per_rad
        mode = registers.operating_mode
        if mode in (POSITION_MODE, EXTENDED_POSITION_MODE):
            speed_cap = registers.speed_cap_rad_s
            position_error = registers.goal_angle_rad - motor_angle_rad
            speed_command = max(
                -speed_cap, min(speed_cap, registers.position_gain_per_s * position_error)
            )
        elif mode == VELOCITY_MODE:
            speed_command = registers.goal_velocity_rad_s
        else:  # torque mode: the current loop follows Goal Torque directly
            torque = registers.goal_torque_a * self.params.torque_constant_nm_per_a
            return ServoOutput(True, motor_velocity_rad_s + torque / kv, torque_cap)
        speed_error = speed_command - motor_velocity_rad_s
        proportional = kv * speed_error
        # Anti-windup: integrate only while the output is not clipped (or is unwinding).
        unclipped = proportional + self.integral_nm
        if abs(unclipped) < torque_cap or (unclipped * speed_error) < 0:
            self.integral_nm += registers.integral_rate_nm_per_rad * speed_error * dt_s
            self.integral_nm = max(-torque_cap, min(torque_cap, self.integral_nm))
        return ServoOutput(True, speed_command + self.integral_nm / kv, torque_cap)

    def report(
        self,
        motor_torque_nm: float,
        motor_angle_rad: float,
        motor_velocity_rad_s: float,
        dt_s: float,
        current_noise_a: float = 0.0,
        velocity_noise_rad_s: float = 0.0,
    ) -> None:
        """Write the Present* items after a physics step and run the overload protection.

        current_noise_a, velocity_noise_rad_s: this step's measurement noise (the current the
        firmware measures is also what its overload protection sees)."""
        p = self.params
        registers = self.registers
        current_a = motor_torque_nm / p.torque_constant_nm_per_a + current_noise_a
        self.last_current_a = current_a
        measured_velocity = motor_velocity_rad_s + velocity_noise_rad_s
        self.table.set_measurements(
            Measurements(
                moving=int(abs(motor_velocity_rad_s) > registers.moving_threshold_rad_s),
                position_pulses=_round_to_int32(
                    motor_angle_rad / RAD_PER_PULSE - registers.homing_offset_pulses
                ),
                velocity_units=_round_to_int32(measured_velocity / RAD_S_PER_VELOCITY_UNIT),
                current_units=_clamp_int16(round(current_a / AMPERE_PER_CURRENT_UNIT)),
                input_voltage_decivolts=round(p.input_voltage_v * 10),
                temperature_c=round(p.temperature_c),
            )
        )
        self._run_overload_protection(abs(current_a), dt_s)

    def _run_overload_protection(self, current_a: float, dt_s: float) -> None:
        if not self.table.torque_enabled:
            self.overload_timer_s = 0.0
            return
        cap_a = self.registers.current_cap_a
        near_limit = current_a >= self.params.overload_current_fraction * cap_a
        self.overload_timer_s += dt_s if near_limit else -dt_s
        self.overload_timer_s = max(0.0, self.overload_timer_s)
        if self.overload_timer_s >= self.params.overload_trip_time_s:
            self.table.raise_hardware_error(OVERLOAD_BIT)
            self.overload_timer_s = 0.0


def _round_to_int32(value: float) -> int:
    return max(-(2**31), min(2**31 - 1, round(value)))


def _clamp_int16(value: int) -> int:
    return max(-32768, min(32767, value))
