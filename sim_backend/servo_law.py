"""The H54 servo law of servo.py, written for numpy arrays and for Python numbers.

`velocity_loop`, `overload_timer` and `to_device_units` are the law's text, written once for
arrays (`ARRAY`) and Python numbers (`SCALAR`: a bank of one runs on them, numpy costs more
than the law on one joint). The selections are the only operations that differ (`ops.where`,
`ops.clip`, `ops.round`); clip is max(low, min(high, x)) and round is half to even in both, so
both give the same floats, bit for bit.

`InPlaceLaw` is the same text for n joints, operation for operation, on preallocated arrays
(`out=`): what `H54FirmwareBank` (servo_bank.py) runs every physics step. On 12 numbers a numpy
call costs ~0.4 us and its arithmetic nothing, so the step's cost is its number of calls: no
temporaries, no selection where every joint is on and in a position mode, no overload timer
arithmetic while every timer is 0 and no current is near its threshold (the timers then stay
0: max(0, 0 - dt) = 0). tests/sim_backend/test_firmware_bank_equivalence.py holds both to a
per-joint reference of the documented law, byte for byte. `Decoded` holds the registers of n
joints as the arrays the law reads.
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any, NamedTuple

import numpy as np

from sim_backend.servo import (
    EXTENDED_POSITION_MODE,
    POSITION_MODE,
    VELOCITY_MODE,
    H54ServoParams,
    Registers,
)

_INT32_MIN, _INT32_MAX = -(2**31), 2**31 - 1
_INT16_MIN, _INT16_MAX = -32768, 32767


class Decoded:
    """The registers of all joints as arrays (SI), refreshed per joint after a write."""

    def __init__(self, n: int) -> None:
        self.position_gain = np.zeros(n)
        self.velocity_gain = np.ones(n)
        self.integral_rate = np.zeros(n)
        self.current_cap_a = np.zeros(n)
        self.torque_cap_nm = np.zeros(n)
        self.speed_cap = np.zeros(n)
        self.goal_angle = np.zeros(n)
        self.goal_velocity = np.zeros(n)
        self.goal_torque_nm = np.zeros(n)
        self.position_mode = np.zeros(n, dtype=bool)
        self.velocity_mode = np.zeros(n, dtype=bool)
        self.torque_mode = np.zeros(n, dtype=bool)
        self.homing_offset_pulses = np.zeros(n)
        self.moving_threshold = np.zeros(n)
        self.torque_on = np.zeros(n, dtype=bool)
        self.torque_off = np.ones(n, dtype=bool)
        self.not_torque_mode = np.ones(n, dtype=bool)
        self.neg_speed_cap = np.zeros(n)
        self.neg_torque_cap_nm = np.zeros(n)
        self.overload_threshold_a = np.zeros(n)
        self.all_position_mode = True
        self.all_on = False
        self.registers: list[Registers | None] = [None] * n

    def first(self) -> SimpleNamespace:
        """Joint 0's figures as Python numbers (a bank of one runs the law on them)."""
        return SimpleNamespace(
            **{
                name: value[0].item() if isinstance(value, np.ndarray) else value
                for name, value in vars(self).items()
                if name not in ("registers", "torque_off", "not_torque_mode")
            }
        )

    def store(self, joint: int, r: Registers, torque_on: bool, params: H54ServoParams) -> None:
        kt = params.torque_constant_nm_per_a
        self.registers[joint] = r
        self.position_gain[joint] = r.position_gain_per_s
        self.velocity_gain[joint] = r.velocity_gain_nms_per_rad
        self.integral_rate[joint] = r.integral_rate_nm_per_rad
        self.current_cap_a[joint] = r.current_cap_a
        self.torque_cap_nm[joint] = r.current_cap_a * kt
        self.speed_cap[joint] = r.speed_cap_rad_s
        self.goal_velocity[joint] = r.goal_velocity_rad_s
        self.goal_torque_nm[joint] = r.goal_torque_a * kt
        mode = r.operating_mode
        self.position_mode[joint] = mode in (POSITION_MODE, EXTENDED_POSITION_MODE)
        self.velocity_mode[joint] = mode == VELOCITY_MODE
        self.torque_mode[joint] = not (self.position_mode[joint] or self.velocity_mode[joint])
        self.homing_offset_pulses[joint] = r.homing_offset_pulses
        self.moving_threshold[joint] = r.moving_threshold_rad_s
        self.torque_on[joint] = torque_on
        self.torque_off[joint] = not torque_on
        self.not_torque_mode[joint] = not self.torque_mode[joint]
        self.neg_speed_cap[joint] = -self.speed_cap[joint]
        self.neg_torque_cap_nm[joint] = -self.torque_cap_nm[joint]
        self.overload_threshold_a[joint] = params.overload_current_fraction * r.current_cap_a
        self.all_position_mode = bool(self.position_mode.all())
        self.all_on = bool(self.torque_on.all())


class JointView:
    """One joint's decoded figures as Python numbers, read from the arrays on demand."""

    def __init__(self, decoded: Decoded, joint: int) -> None:
        self._decoded = decoded
        self._joint = joint

    def __getattr__(self, name: str) -> Any:
        return getattr(self._decoded, name)[self._joint].item()


class _ArrayOps:
    """The law's selections on numpy arrays (elementwise, as the scalar ones)."""

    @staticmethod
    def clip(value: Any, low: Any, high: Any) -> Any:
        return np.maximum(low, np.minimum(high, value))

    where = staticmethod(np.where)
    maximum = staticmethod(np.maximum)
    round = staticmethod(np.rint)  # half to even, as Python's round


class _ScalarOps:
    """The law's selections on Python numbers."""

    @staticmethod
    def clip(value: Any, low: Any, high: Any) -> Any:
        return max(low, min(high, value))

    @staticmethod
    def where(condition: Any, if_true: Any, if_false: Any) -> Any:
        return if_true if condition else if_false

    maximum = staticmethod(max)
    round = staticmethod(round)


ARRAY, SCALAR = _ArrayOps(), _ScalarOps()


def velocity_loop(
    ops: Any, d: Any, angle: Any, velocity: Any, integral: Any, dt_s: float
) -> tuple[Any, Any]:
    """servo.py's cascade, device frame: (the velocity-loop input, the new integral [N m]).

    Position modes: w* = Kpp (goal - angle) clipped to the speed cap; velocity mode: w* = Goal
    Velocity; the torque kv (w* - w) + integral is clipped to the cap by MuJoCo, and the
    integral (of kv/Ti (w* - w)) integrates only while that torque is not clipped or it is
    unwinding, itself clipped to the cap. Torque mode: the current loop follows Goal Torque
    (the integral is left alone). Torque off: the integral resets. Written once for numpy
    arrays (`ARRAY`) and Python numbers (`SCALAR`)."""
    speed_command = ops.clip(d.position_gain * (d.goal_angle - angle), d.neg_speed_cap, d.speed_cap)
    if not d.all_position_mode:
        speed_command = ops.where(d.velocity_mode, d.goal_velocity, speed_command)
    speed_error = speed_command - velocity
    unclipped = d.velocity_gain * speed_error + integral
    integrate = (abs(unclipped) < d.torque_cap_nm) | (unclipped * speed_error < 0)
    integrated = ops.clip(
        integral + d.integral_rate * speed_error * dt_s, d.neg_torque_cap_nm, d.torque_cap_nm
    )
    new_integral = ops.where(integrate, integrated, integral)
    command = speed_command + new_integral / d.velocity_gain
    if not d.all_position_mode:
        new_integral = ops.where(d.torque_mode, integral, new_integral)
        command = ops.where(d.torque_mode, velocity + d.goal_torque_nm / d.velocity_gain, command)
    return command, ops.where(d.torque_on, new_integral, 0.0)


def overload_timer(ops: Any, d: Any, current_abs_a: Any, timer_s: Any, dt_s: float) -> Any:
    """servo.py's overload rule: the timer runs up while |I| >= the fraction of the current
    cap, down (at the same rate) below it, never below 0; reset while torque is off."""
    near_limit = current_abs_a >= d.overload_threshold_a
    timer_s = ops.where(near_limit, timer_s + dt_s, timer_s - dt_s)
    return ops.where(d.torque_on, ops.maximum(0.0, timer_s), 0.0)


def to_device_units(
    ops: Any,
    angle: Any,
    velocity: Any,
    measured_velocity: Any,
    current: Any,
    homing_offset_pulses: Any,
    moving_threshold_rad_s: Any,
    units: UnitFactors,
) -> tuple[Any, Any, Any, Any]:
    """(Moving, Present Position, Present Velocity, Present Current) in the control table's
    units (the model's: e.g. the H54-200-S500-R's pulses, 0.00199234 rpm, 16.11328 mA), rounded
    half to even and saturated to the items' sizes; the device frame in, Homing Offset
    subtracted from the position."""
    return (
        abs(velocity) > moving_threshold_rad_s,
        ops.clip(
            ops.round(angle / units.rad_per_pulse - homing_offset_pulses), _INT32_MIN, _INT32_MAX
        ),
        ops.clip(
            ops.round(measured_velocity / units.rad_s_per_velocity_unit), _INT32_MIN, _INT32_MAX
        ),
        ops.clip(ops.round(current / units.ampere_per_current_unit), _INT16_MIN, _INT16_MAX),
    )


class UnitFactors(NamedTuple):
    """The unit factors `to_device_units` divides by: Python numbers for one joint, arrays (one
    entry per joint, each its model's) for a bank."""

    rad_per_pulse: Any
    rad_s_per_velocity_unit: Any
    ampere_per_current_unit: Any


class InPlaceLaw:
    """`velocity_loop` and `overload_timer` for n joints on preallocated arrays: the same
    operations in the same order, each numpy call writing into a buffer (see the module
    docstring). Integral and timers are updated in place."""

    def __init__(self, n: int) -> None:
        self.speed = np.zeros(n)  # w*
        self.error = np.zeros(n)  # w* - w
        self.unclipped = np.zeros(n)
        self.scratch = np.zeros(n)
        self.down = np.zeros(n)
        self.command = np.zeros(n)
        self.integrate = np.zeros(n, dtype=bool)
        self.unwinding = np.zeros(n, dtype=bool)
        self.near = np.zeros(n, dtype=bool)
        self.tripped = np.zeros(n, dtype=bool)
        self.timers_idle = True  # every timer is 0 (then no current near: they stay 0)

    def velocity_loop(
        self, d: Decoded, angle: np.ndarray, velocity: np.ndarray, integral: np.ndarray, dt_s: float
    ) -> np.ndarray:
        """`velocity_loop(ARRAY, ...)`: returns the velocity-loop input (a buffer, valid until
        the next call) and leaves the new integral in `integral`."""
        speed, error, unclipped, t = self.speed, self.error, self.unclipped, self.scratch
        integrate, unwinding = self.integrate, self.unwinding
        np.subtract(d.goal_angle, angle, out=speed)
        np.multiply(d.position_gain, speed, out=speed)
        np.minimum(d.speed_cap, speed, out=speed)  # clip: max(low, min(high, x))
        np.maximum(d.neg_speed_cap, speed, out=speed)
        if not d.all_position_mode:
            np.copyto(speed, d.goal_velocity, where=d.velocity_mode)
        np.subtract(speed, velocity, out=error)
        np.multiply(d.velocity_gain, error, out=unclipped)
        np.add(unclipped, integral, out=unclipped)
        np.abs(unclipped, out=t)
        np.less(t, d.torque_cap_nm, out=integrate)
        # every torque inside its cap (the usual): every integral integrates, whatever the
        # unwinding test says
        every = d.all_position_mode and np.count_nonzero(integrate) == len(integral)
        if not every:
            np.multiply(unclipped, error, out=t)
            np.less(t, 0, out=unwinding)
            np.logical_or(integrate, unwinding, out=integrate)
            if not d.all_position_mode:  # torque mode: the integral is left alone
                np.logical_and(integrate, d.not_torque_mode, out=integrate)
        np.multiply(d.integral_rate, error, out=t)
        np.multiply(t, dt_s, out=t)
        np.add(integral, t, out=t)
        np.minimum(d.torque_cap_nm, t, out=t)
        if every:
            np.maximum(d.neg_torque_cap_nm, t, out=integral)
        else:
            np.maximum(d.neg_torque_cap_nm, t, out=t)
            np.copyto(integral, t, where=integrate)
        command = self.command
        np.divide(integral, d.velocity_gain, out=command)
        np.add(speed, command, out=command)
        if not d.all_position_mode:
            np.divide(d.goal_torque_nm, d.velocity_gain, out=t)
            np.add(velocity, t, out=t)
            np.copyto(command, t, where=d.torque_mode)
        if not d.all_on:
            np.copyto(integral, 0.0, where=d.torque_off)
        return command

    def overload_timer(
        self, d: Decoded, current_a: np.ndarray, timer_s: np.ndarray, dt_s: float
    ) -> None:
        """`overload_timer(ARRAY, ...)` into `timer_s`; `tripped` marks the timers that reached
        `trip_s` (see `trips`)."""
        near, t = self.near, self.scratch
        np.abs(current_a, out=t)
        np.greater_equal(t, d.overload_threshold_a, out=near)
        if self.timers_idle and not np.count_nonzero(near):
            return  # every timer 0, no current near: max(0, 0 - dt) = 0
        np.add(timer_s, dt_s, out=t)
        np.subtract(timer_s, dt_s, out=self.down)
        np.copyto(self.down, t, where=near)
        np.maximum(0.0, self.down, out=timer_s)
        if not d.all_on:
            np.copyto(timer_s, 0.0, where=d.torque_off)
        self.timers_idle = not np.count_nonzero(timer_s)

    def trips(self, timer_s: np.ndarray, trip_s: np.ndarray) -> bool:
        """Whether any timer reached its trip time (marked in `tripped`); none while idle."""
        if self.timers_idle:
            return False
        np.greater_equal(timer_s, trip_s, out=self.tripped)
        return bool(np.count_nonzero(self.tripped))
