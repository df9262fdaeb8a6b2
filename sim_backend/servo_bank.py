"""n PRO firmwares stepped together: the servo law of servo.py on numpy arrays over joints (each
joint in its own model's units and items: the tables say which).

The law, the defaults and the overload rule are documented in sim_backend/servo.py (its
docstring is the spec) and written out in servo_law.py; this module runs them for all n
actuators of a plant in one update per physics step instead of n Python calls:

    command(angles, velocities)     before the step: per joint, torque on or off, the
                                    velocity-loop input and the torque cap (position loop,
                                    speed cap, velocity-loop integral with anti-windup; velocity
                                    and torque modes; dynamic brake while off)
    measure(torques, angles, velocities)
                                    after the step: the measured current (with its noise) runs
                                    the overload timers; the Present* items are NOT written here

The control tables are touched only when they change or are read:
- registers are decoded again only for a joint whose table's `revision` moved (a write; tables
  that count on a shared `WriteCounter` show with one comparison that none moved), only Goal
  Position when nothing else was written (`goal_position_writes`: the host's every tick);
- the Present* items of a table are written when the bus reads them: a table with
  `attach_measurement_source` calls back before any read that may cover them, and the bank
  converts the last step's state to device units then (all joints at once, once per step).

Angles and velocities in and out are physical (the plant's frame); the bank maps them through
each actuator's mounting (direction, offset) to the device frame its firmware works in.

Noise: the Present Current (and, with `velocity_noise`, Present Velocity) noise of every step,
from one seeded Generator in joint order (`ServoNoise`, sim_backend/servo_noise.py).

Per step the law runs in place on preallocated arrays (`InPlaceLaw`, servo_law.py); `command`
returns the bank's buffers, and the plant's caps, gains and brakes move only with
`limits_revision` (a decode of anything but Goal Position, torque on or off).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

import numpy as np

from sim_backend.servo import (
    OVERLOAD_BIT,
    ControlTable,
    H54ServoParams,
    Measurements,
    Registers,
    WriteCounter,
    decode_registers,
    goal_angle_rad,
)
from sim_backend.servo_law import (
    ARRAY,
    SCALAR,
    Decoded,
    InPlaceLaw,
    JointView,
    UnitFactors,
    overload_timer,
    to_device_units,
    velocity_loop,
)
from sim_backend.servo_noise import ServoNoise


@dataclass
class ServoCommands:
    """What the firmwares ask of the motors this step (physical frame, arrays of n)."""

    torque_on: np.ndarray  # bool
    velocity_command_rad_s: np.ndarray  # the implicit velocity-loop input (includes the I term)
    torque_limit_nm: np.ndarray  # 0 where torque is off
    velocity_gain_nms_per_rad: np.ndarray  # kv; kept at its last torque-on value while off
    brake_damping_nms_per_rad: np.ndarray  # the dynamic brake: 0 where torque is on


class H54FirmwareBank:
    """The firmwares of n actuators, one control table each (see the module docstring).

    directions / offsets_rad: each actuator's mounting (device = direction * physical + offset).
    rng: the measurement noise's Generator (None: no noise is drawn).
    velocity_noise: draw Present Velocity noise too (the testbed does; the humanoid draws only
        the current's, as it always has: its logs stay comparable run to run).
    """

    def __init__(
        self,
        tables: Sequence[ControlTable],
        params: Sequence[H54ServoParams],
        *,
        directions: Sequence[int] | None = None,
        offsets_rad: Sequence[float] | None = None,
        rng: np.random.Generator | None = None,
        velocity_noise: bool = True,
    ) -> None:
        n = len(tables)
        if n == 0 or len(params) != n:
            raise ValueError("a firmware bank needs one H54ServoParams per control table")
        self.tables = list(tables)
        self.params = list(params)
        self.n = n
        self.direction = np.asarray(directions if directions is not None else [1] * n, float)
        self.offset_rad = np.asarray(offsets_rad if offsets_rad is not None else [0.0] * n, float)
        if self.direction.shape != (n,) or self.offset_rad.shape != (n,):
            raise ValueError("directions and offsets_rad need one entry per control table")

        def figure(name: str) -> np.ndarray:
            return np.array([getattr(p, name) for p in self.params], dtype=float)

        # each table's units (its model's): arrays for the bank, Python numbers for a bank of one
        units = [table.model.units for table in self.tables]
        self._rad_per_pulse = [u.rad_per_pulse for u in units]
        self._unit_factors = UnitFactors(
            np.array(self._rad_per_pulse),
            np.array([u.rad_s_per_velocity_unit for u in units]),
            np.array([u.ampere_per_current_unit for u in units]),
        )
        self._unit_factors_one = UnitFactors(
            units[0].rad_per_pulse,
            units[0].rad_s_per_velocity_unit,
            units[0].ampere_per_current_unit,
        )
        self.torque_constant = figure("torque_constant_nm_per_a")
        self.brake_damping = figure("dynamic_brake_damping_nms_per_rad")
        self.overload_trip_s = figure("overload_trip_time_s")
        self._noise = ServoNoise(
            figure("current_noise_a"),
            figure("velocity_noise_rad_s") if velocity_noise else np.zeros(n),
            rng,
        )
        self._velocity_noisy = self._noise.velocity_noisy
        self._voltage_decivolts = [round(p.input_voltage_v * 10) for p in self.params]
        self._temperature_c = [round(p.temperature_c) for p in self.params]
        self._identity_mounting = bool(np.all(self.direction == 1) and not self.offset_rad.any())

        self.integral_nm = np.zeros(n)
        self.overload_timer_s = np.zeros(n)
        self.last_current_a = np.zeros(n)
        self._decoded = Decoded(n)
        self._law = InPlaceLaw(n)
        self._revisions = [-1] * n
        # tables that count their writes on a shared counter: no write, nothing to look at
        self._writes: WriteCounter | None = None
        if all(hasattr(table, "add_write_counter") for table in self.tables):
            self._writes = WriteCounter()
            for table in self.tables:
                table.add_write_counter(self._writes)
        self._writes_seen = -1
        self._goal_writes: list[int | None] = [None] * n
        # counts the decodes of registers other than Goal Position (caps, gains, modes, torque):
        # what the plant's actuators follow changes only then
        self.limits_revision = 0
        self._limits_applied = -1
        self._first = SimpleNamespace()
        self._direction_one = self.direction[0].item()
        self._offset_one = self.offset_rad[0].item()
        self._refresh_registers()
        # a step's commands, in buffers (the arrays `command` returns)
        self._commands = ServoCommands(
            torque_on=self._decoded.torque_on,
            velocity_command_rad_s=self._law.command,
            torque_limit_nm=np.zeros(n),
            velocity_gain_nms_per_rad=self._decoded.velocity_gain.copy(),
            brake_damping_nms_per_rad=np.zeros(n),
        )
        self._device_angle = np.zeros(n)  # a step's input in the device frame (mounted banks)
        self._device_velocity = np.zeros(n)
        self._device_torque = np.zeros(n)
        # the last step's state, physical frame, for the lazy Present* items (converted to
        # device units when the bus reads them)
        self._angle = np.zeros(n)
        self._velocity = np.zeros(n)
        self._velocity_noise_measured = np.zeros(n)
        self._registers_measured: list[Registers | None] = list(self._decoded.registers)
        self._registers_measured_at = self.limits_revision
        self._sample = 0  # counts measure() calls
        self._written = [0] * n  # the sample each table last got (-1: due after a report_joint)
        self._units: tuple[int, list[Measurements]] | None = None
        for joint, table in enumerate(self.tables):
            attach = getattr(table, "attach_measurement_source", None)
            if attach is not None:
                attach(lambda joint=joint: self.write_measurements(joint))

    # --- registers ----------------------------------------------------------------------------
    def registers(self, joint: int) -> Registers:
        """One joint's registers in SI, decoded again only after a write."""
        self._refresh_registers()
        registers = self._decoded.registers[joint]
        assert registers is not None
        return registers

    def velocity_gains(self) -> np.ndarray:
        self._refresh_registers()
        return self._decoded.velocity_gain.copy()

    def goal_angle_rad(self, joint: int) -> float:
        self._refresh_registers()
        return self._decoded.goal_angle[joint].item()

    def _refresh_registers(self) -> None:
        """Decode the registers of the joints whose table was written since the last call:
        only Goal Position when nothing else was (the host writes it every tick)."""
        writes = self._writes
        if writes is not None:
            if writes.count == self._writes_seen:
                return
            self._writes_seen = writes.count
        revisions = [table.revision for table in self.tables]
        if revisions == self._revisions:
            return
        decoded = self._decoded
        for joint, (table, revision) in enumerate(zip(self.tables, revisions, strict=True)):
            if revision == self._revisions[joint]:
                continue
            goal_writes = getattr(table, "goal_position_writes", None)
            registers = decoded.registers[joint]
            goal_only = (
                registers is not None
                and goal_writes is not None
                and revision - self._revisions[joint] == goal_writes - self._goal_writes[joint]
            )
            if not goal_only:
                params = self.params[joint]
                registers = decode_registers(table, params)
                decoded.store(joint, registers, table.torque_enabled, params)
                self.limits_revision += 1
            assert registers is not None
            decoded.goal_angle[joint] = goal_angle_rad(
                table.item("Goal Position"),
                registers.homing_offset_pulses,
                self._rad_per_pulse[joint],
            )
            self._goal_writes[joint] = goal_writes
        self._revisions = revisions
        if self.n == 1:
            self._first = self._decoded.first()

    # --- one physics step ---------------------------------------------------------------------
    def command(
        self, angles_rad: np.ndarray, velocities_rad_s: np.ndarray, dt_s: float
    ) -> ServoCommands:
        """The velocity-loop inputs and torque caps for this step (servo.py's law on arrays).
        The arrays returned are the bank's buffers, valid until the next call; the caps, gains
        and brakes change only when `limits_revision` does."""
        self._refresh_registers()
        d = self._decoded
        if self._identity_mounting:
            angles, velocities = angles_rad, velocities_rad_s
        else:
            angles, velocities = self._device_angle, self._device_velocity
            np.multiply(self.direction, angles_rad, out=angles)
            np.add(angles, self.offset_rad, out=angles)
            np.multiply(self.direction, velocities_rad_s, out=velocities)
        command = self._law.velocity_loop(d, angles, velocities, self.integral_nm, dt_s)
        if not self._identity_mounting:
            np.multiply(self.direction, command, out=command)
        out = self._commands
        if self._limits_applied != self.limits_revision:
            self._limits_applied = self.limits_revision
            self._update_limits(d, out)
        if not d.all_on:
            np.copyto(command, 0.0, where=d.torque_off)
        return out

    def _update_limits(self, d: Decoded, out: ServoCommands) -> None:
        """Torque caps (0 where off), kv (kept at its last torque-on value while off) and the
        dynamic brakes (where off), after registers or torque changed."""
        np.copyto(out.velocity_gain_nms_per_rad, d.velocity_gain, where=d.torque_on)
        if d.all_on:
            np.copyto(out.torque_limit_nm, d.torque_cap_nm)
            out.brake_damping_nms_per_rad.fill(0.0)
            return
        np.copyto(out.torque_limit_nm, np.where(d.torque_on, d.torque_cap_nm, 0.0))
        np.copyto(out.brake_damping_nms_per_rad, np.where(d.torque_on, 0.0, self.brake_damping))

    def command_one(
        self, angle_rad: float, velocity_rad_s: float, dt_s: float
    ) -> tuple[bool, float, float]:
        """`command` for a bank of one in Python numbers (numpy costs more than the law on one
        joint): (torque on, velocity-loop input, torque cap), physical frame."""
        self._refresh_registers()
        d = self._first
        direction = self._direction_one
        command, integral = velocity_loop(
            SCALAR,
            d,
            direction * angle_rad + self._offset_one,
            direction * velocity_rad_s,
            self.integral_nm[0].item(),
            dt_s,
        )
        self.integral_nm[0] = integral
        if not d.torque_on:
            return False, 0.0, 0.0
        return True, direction * command, d.torque_cap_nm

    def measure(
        self,
        torques_nm: np.ndarray,
        angles_rad: np.ndarray,
        velocities_rad_s: np.ndarray,
        dt_s: float,
        *,
        current_noise_a: np.ndarray | None = None,
        velocity_noise_rad_s: np.ndarray | None = None,
    ) -> None:
        """After the step: the measured current runs the overload protection; the state is kept
        for the Present* items (written when read). The noise is this step's draw unless given."""
        self._refresh_registers()
        if current_noise_a is None or velocity_noise_rad_s is None:
            current_noise_a, velocity_noise_rad_s = self._noise.draw()
        np.copyto(self._angle, angles_rad)
        np.copyto(self._velocity, velocities_rad_s)
        if self._velocity_noisy:
            np.copyto(self._velocity_noise_measured, velocity_noise_rad_s)
        torques = torques_nm
        if not self._identity_mounting:
            torques = np.multiply(self.direction, torques_nm, out=self._device_torque)
        current = self.last_current_a
        np.divide(torques, self.torque_constant, out=current)
        np.add(current, current_noise_a, out=current)
        d, law = self._decoded, self._law
        law.overload_timer(d, current, self.overload_timer_s, dt_s)
        if law.trips(self.overload_timer_s, self.overload_trip_s):
            self._trip(law.tripped)
        if self._registers_measured_at != self.limits_revision:
            self._registers_measured_at = self.limits_revision
            self._registers_measured = list(d.registers)
        self._sample += 1

    def measure_one(
        self, torque_nm: float, angle_rad: float, velocity_rad_s: float, dt_s: float
    ) -> None:
        """`measure` for a bank of one in Python numbers (see `command_one`)."""
        self._refresh_registers()
        self._measure_joint(0, torque_nm, angle_rad, velocity_rad_s, dt_s)
        self._registers_measured = list(self._decoded.registers)
        self._registers_measured_at = self.limits_revision
        self._sample += 1

    def report_joint(
        self, joint: int, torque_nm: float, angle_rad: float, velocity_rad_s: float, dt_s: float
    ) -> None:
        """`measure` for one joint alone (at power-on, after its REBOOT), drawing its noise as
        a step does."""
        self._refresh_registers()
        self._measure_joint(joint, torque_nm, angle_rad, velocity_rad_s, dt_s)
        self._registers_measured[joint] = self._decoded.registers[joint]
        self._written[joint] = -1  # this joint's Present* items are due again
        self._units = None

    def _measure_joint(
        self, joint: int, torque_nm: float, angle_rad: float, velocity_rad_s: float, dt_s: float
    ) -> None:
        current_noise, velocity_noise = self._noise.draw_joint(joint)
        direction = self.direction[joint].item()
        self._angle[joint] = angle_rad
        self._velocity[joint] = velocity_rad_s
        self._velocity_noise_measured[joint] = velocity_noise
        current = direction * torque_nm / self.torque_constant[joint].item() + current_noise
        self.last_current_a[joint] = current
        d = self._first if self.n == 1 else JointView(self._decoded, joint)
        timer = overload_timer(SCALAR, d, abs(current), self.overload_timer_s[joint].item(), dt_s)
        self.overload_timer_s[joint] = timer
        self._law.timers_idle = False  # (the next step's update finds out)
        if timer >= self.overload_trip_s[joint]:
            self._trip(joint)

    def on_reboot(self, joint: int) -> None:
        self.integral_nm[joint] = 0.0
        self.overload_timer_s[joint] = 0.0

    def _trip(self, tripped: Any) -> None:
        """The Overload bit for these joints (a mask, or one index); their timers restart."""
        joints = [tripped] if isinstance(tripped, int) else np.flatnonzero(tripped).tolist()
        for joint in joints:
            self.tables[joint].raise_hardware_error(OVERLOAD_BIT)
            self.overload_timer_s[joint] = 0.0

    # --- the Present* items, when the bus reads them ------------------------------------------
    def measurements(self, joint: int) -> Measurements:
        """Joint `joint`'s Present* items from the last measured state [device units]."""
        units = self._units
        if units is None or units[0] != self._sample:
            units = (self._sample, self._device_units())
            self._units = units
        return units[1][joint]

    def write_measurements(self, joint: int) -> None:
        """Write the Present* items into joint `joint`'s table if the last step's are not
        there yet (the table calls this before a read that may cover them)."""
        if self._written[joint] != self._sample:
            self._written[joint] = self._sample
            self.tables[joint].set_measurements(self.measurements(joint))

    def _device_units(self) -> list[Measurements]:
        """The last measured state in the control table's units, for all joints at once."""
        registers = self._registers_measured
        homing = [r.homing_offset_pulses if r else 0 for r in registers]
        threshold = [r.moving_threshold_rad_s if r else 0.0 for r in registers]
        if self.n == 1:  # Python numbers: cheaper than numpy for one joint
            direction = self._direction_one
            velocity = direction * self._velocity[0].item()
            measured = velocity + self._velocity_noise_measured[0].item()
            angle = direction * self._angle[0].item() + self._offset_one
            current = self.last_current_a[0].item()
            units = to_device_units(
                SCALAR,
                angle,
                velocity,
                measured,
                current,
                *homing,
                *threshold,
                self._unit_factors_one,
            )
            return self._rows([[int(value)] for value in units])
        angle, velocity = self._angle, self._velocity
        if not self._identity_mounting:  # the device frame, as the law saw it
            angle = self.direction * angle + self.offset_rad
            velocity = self.direction * velocity
        measured = velocity + self._velocity_noise_measured if self._velocity_noisy else velocity
        units = to_device_units(
            ARRAY,
            angle,
            velocity,
            measured,
            self.last_current_a,
            np.array(homing, float),
            np.array(threshold),
            self._unit_factors,
        )
        return self._rows([value.astype(np.int64).tolist() for value in units])

    def _rows(self, units: list[list[int]]) -> list[Measurements]:
        """Per joint, (Moving, Present Position, Velocity, Current, Input Voltage, Temperature)."""
        columns = zip(*units, self._voltage_decivolts, self._temperature_c, strict=True)
        return list(map(Measurements._make, columns))
