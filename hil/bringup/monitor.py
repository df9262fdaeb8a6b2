"""`hil monitor`: every joint's readings at a steady rate, judged against the configuration.

The bus is opened read-only (`make_bus(..., read_only=True)`: no EEPROM or RAM write, every
command refused by the driver), so the monitor leaves the robot as it found it, torque included:
if an actuator has torque on, the monitor says so and leaves it on.

What is flagged per joint (`Flag`), each against a value of the configuration:
    NO_REPLY          the actuator did not answer this read
    FAULT             the actuator reports a hardware error (its own protection: overload,
                      overheating, input voltage, ...; the device's code is shown)
    TORQUE_ON         the actuator's torque is on (somebody else is driving it)
    OUT_OF_RANGE      the motor angle is outside [min_angle_rad, max_angle_rad]
    OFFSETS_DISAGREE  |link - motor| > [safety] zero_offset_margin_rad: at rest, the zero
                      offsets are wrong (the start gate would refuse a run)
    DEFLECTION        |link - motor| > [safety] max_deflection_rad (the supervisor's bound)
    LINK_STALE        no fresh link-encoder value this read
    CURRENT           |current| above [safety] current_guard_fraction of the current limit
Temperature and input voltage are shown as read; the actuator's own limits on them act through
its hardware-error bits (FAULT).
"""

from __future__ import annotations

import enum
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from drivers.joint_bus import ActuatorFault, Diagnostic, JointBus, JointSample
from hil.config import Config

# The longest a wait between samples sleeps at a time: a stop (Ctrl-C, SIGTERM) or the end of
# --duration is seen within this, however slow the rate.
MAX_SLEEP_S = 0.05


class Flag(enum.StrEnum):
    NO_REPLY = "no_reply"
    FAULT = "fault"
    TORQUE_ON = "torque_on"
    OUT_OF_RANGE = "out_of_range"
    OFFSETS_DISAGREE = "offsets_disagree"
    DEFLECTION = "deflection"
    LINK_STALE = "link_stale"
    CURRENT = "current"


@dataclass(frozen=True)
class JointStatus:
    """One joint at one read, SI units (NaN: not read), and what is wrong with it."""

    name: str
    actuator: str  # its actuator's model (the configuration's; open() checked it by PING)
    motor_angle_rad: float
    link_angle_rad: float
    deflection_rad: float
    motor_velocity_rad_s: float
    motor_current_a: float
    temperature_c: float
    input_voltage_v: float
    actuator_fault: int  # ActuatorFault flags
    fault_code: int  # the device's own code
    torque_enabled: bool
    link_age_s: float
    flags: tuple[Flag, ...]

    def record(self) -> dict[str, Any]:
        """Plain JSON data (NaN and infinity as null)."""
        out: dict[str, Any] = {}
        for key, value in vars(self).items():
            if isinstance(value, float):
                out[key] = value if math.isfinite(value) else None
            elif key == "flags":
                out[key] = [str(flag) for flag in value]
            else:
                out[key] = value
        out["fault"] = ActuatorFault.describe(self.actuator_fault)
        return out


@dataclass(frozen=True)
class MonitorSample:
    time_s: float  # since the monitor started
    joints: tuple[JointStatus, ...]

    @property
    def flagged(self) -> bool:
        return any(joint.flags for joint in self.joints)

    def record(self) -> dict[str, Any]:
        return {"time_s": round(self.time_s, 6), "joints": [j.record() for j in self.joints]}


def assess(
    config: Config, sample: JointSample, current_limits_a: np.ndarray, time_s: float = 0.0
) -> MonitorSample:
    """Each joint's readings and flags (see the module docstring)."""
    safety = config.safety
    nan = np.full(len(config.joints), math.nan)
    temperature = sample.diagnostics.get(Diagnostic.ACTUATOR_TEMPERATURE_C, nan)
    voltage = sample.diagnostics.get(Diagnostic.ACTUATOR_INPUT_VOLTAGE_V, nan)
    deflection = sample.link_angle_rad - sample.motor_angle_rad
    joints = []
    for i, joint in enumerate(config.joints):
        motor, link = float(sample.motor_angle_rad[i]), float(sample.link_angle_rad[i])
        flags: list[Flag] = []
        if not sample.motor_valid[i]:
            flags.append(Flag.NO_REPLY)
        if int(sample.actuator_fault[i]):
            flags.append(Flag.FAULT)
        if sample.torque_enabled[i]:
            flags.append(Flag.TORQUE_ON)
        if sample.motor_valid[i] and not joint.min_angle_rad <= motor <= joint.max_angle_rad:
            flags.append(Flag.OUT_OF_RANGE)
        gap = abs(float(deflection[i]))
        if gap > safety.zero_offset_margin_rad:
            flags.append(Flag.OFFSETS_DISAGREE)
        if gap > safety.max_deflection_rad:
            flags.append(Flag.DEFLECTION)
        if not sample.link_valid[i]:
            flags.append(Flag.LINK_STALE)
        limit = float(current_limits_a[i])
        current = float(sample.motor_current_a[i])
        if math.isfinite(limit) and abs(current) > safety.current_guard_fraction * limit:
            flags.append(Flag.CURRENT)
        joints.append(
            JointStatus(
                name=joint.name,
                actuator=config.actuator_of(joint),
                motor_angle_rad=motor,
                link_angle_rad=link,
                deflection_rad=float(deflection[i]),
                motor_velocity_rad_s=float(sample.motor_velocity_rad_s[i]),
                motor_current_a=current,
                temperature_c=float(temperature[i]),
                input_voltage_v=float(voltage[i]),
                actuator_fault=int(sample.actuator_fault[i]),
                fault_code=int(sample.fault_code[i]),
                torque_enabled=bool(sample.torque_enabled[i]),
                link_age_s=float(sample.link_age_s[i]),
                flags=tuple(flags),
            )
        )
    return MonitorSample(time_s, tuple(joints))


def monitor(
    config: Config,
    bus: JointBus,
    *,
    rate_hz: float,
    duration_s: float | None,
    on_sample: Callable[[MonitorSample], None],
    on_note: Callable[[str], None],
    stopped: Callable[[], bool] = lambda: False,
    clock: Callable[[], float] = time.monotonic,
    sleep: Callable[[float], None] = time.sleep,
) -> int:
    """Read `bus` (already open, read-only) at `rate_hz` until `duration_s` (None: until
    `stopped()`), handing each assessed sample to `on_sample`. Returns the number of samples.

    Reads are paced on a fixed grid; a read that takes longer than a period is followed at
    once by the next (no catching up in bursts). The wait for the next read ends early at
    `duration_s` or when `stopped()`: it sleeps at most MAX_SLEEP_S at a time.
    """
    limits = np.asarray(bus.current_limits_a(), dtype=float)
    period = 1.0 / rate_hz
    start = grid = clock()
    count = 0
    told_torque = False
    while not stopped():
        now = clock() - start
        if duration_s is not None and now >= duration_s:
            break
        sample = assess(config, bus.read(), limits, now)
        if not told_torque and any(j.torque_enabled for j in sample.joints):
            on_note(
                "torque is ON on "
                + ", ".join(j.name for j in sample.joints if j.torque_enabled)
                + ": the monitor only reads, and leaves it on"
            )
            told_torque = True
        on_sample(sample)
        count += 1
        due = grid + count * period
        if due <= clock():
            grid = clock() - count * period  # late: re-anchor the grid, do not burst
            continue
        end = due if duration_s is None else min(due, start + duration_s)
        wait_until(end, stopped, clock, sleep)
    return count


def wait_until(
    end: float,
    stopped: Callable[[], bool],
    clock: Callable[[], float] = time.monotonic,
    sleep: Callable[[float], None] = time.sleep,
) -> None:
    """Sleep until `clock()` reaches `end` or `stopped()`, in slices of at most MAX_SLEEP_S (a
    signal's handler runs in between; a whole long sleep would be resumed after it, PEP 475)."""
    while not stopped():
        left = end - clock()
        if left <= 0:
            return
        sleep(min(left, MAX_SLEEP_S))
