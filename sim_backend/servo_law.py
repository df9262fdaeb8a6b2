"""The H54 servo law of servo.py, written once for numpy arrays and for Python numbers.

`H54FirmwareBank` (servo_bank.py) runs it on arrays over n joints (`ARRAY`) and, for a bank of
one, on Python numbers (`SCALAR`: numpy costs more than the law on one joint). The selections
are the only operations that differ (`ops.where`, `ops.clip`, `ops.round`); clip is max(low,
min(high, x)) and round is half to even in both, so both give the same floats, bit for bit
(tests/sim_backend/test_firmware_bank_equivalence.py).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from sim_backend.servo import AMPERE_PER_CURRENT_UNIT, RAD_PER_PULSE, RAD_S_PER_VELOCITY_UNIT

_INT32_MIN, _INT32_MAX = -(2**31), 2**31 - 1
_INT16_MIN, _INT16_MAX = -32768, 32767


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
) -> tuple[Any, Any, Any, Any]:
    """(Moving, Present Position, Present Velocity, Present Current) in the control table's
    units (e-Manual: pulses, 0.00199234 rpm, 16.11328 mA), rounded half to even and saturated
    to the items' sizes; the device frame in, Homing Offset subtracted from the position."""
    return (
        abs(velocity) > moving_threshold_rad_s,
        ops.clip(ops.round(angle / RAD_PER_PULSE - homing_offset_pulses), _INT32_MIN, _INT32_MAX),
        ops.clip(ops.round(measured_velocity / RAD_S_PER_VELOCITY_UNIT), _INT32_MIN, _INT32_MAX),
        ops.clip(ops.round(current / AMPERE_PER_CURRENT_UNIT), _INT16_MIN, _INT16_MAX),
    )
