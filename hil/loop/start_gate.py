"""The start gate: tick 0 decides whether torque may go on, before anything moves.

Refused (`StartRefused`, nothing was moved) when, after up to START_READ_ATTEMPTS reads:
    an actuator did not answer, or reports a fault (with --reboot-first: it is rebooted and
    read again; a fault that persists is refused);
    a link sensor did not answer;
    a motor stands outside its joint's range;
    a joint's link-minus-motor angle at rest exceeds the deflection bound (wrong zero offsets
    show up here).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from drivers.joint_bus import ActuatorFault, JointBus, JointDevices, JointSample
from hil.config import Config

START_DEFLECTION_FACTOR = 1.0  # |deflection| at rest must be below the safety bound times this
# The gate reads again before refusing: the supervisor tolerates a lost reply or TPDO during a
# run, so one at the first read should not stop the run either. (Each extra read is a SYNC: in
# lock-step emulation the plant then starts that many periods ahead of tick 0; the widened
# lock-step timeouts make this practically never happen there.)
START_READ_ATTEMPTS = 3

EventLog = Callable[..., None]  # RunLog.event


class StartRefused(RuntimeError):
    """The start gate found a reason not to turn torque on (nothing was moved)."""


def start_gate(
    config: Config,
    sample: JointSample,
    bus: JointBus,
    devices: Sequence[JointDevices],
    reboot_first: bool,
    event: EventLog,
) -> JointSample:
    """Refuse to start, or return the sample to start from (see the module docstring)."""
    sample = _complete(sample, bus, event)
    faulty = _faulty_actuators(config, sample, devices, reboot_first, event)
    if faulty:
        sample = _reboot(config, bus, devices, faulty, event)
    _check_at_rest(config, sample, devices)
    return sample


def _complete(sample: JointSample, bus: JointBus, event: EventLog) -> JointSample:
    for attempt in range(1, START_READ_ATTEMPTS):
        if sample.motor_valid.all() and sample.link_valid.all():
            break
        errors = "; ".join(str(e) for e in sample.bus_errors)
        event(0.0, "start_retry", f"first read incomplete ({errors}): reading again ({attempt})")
        sample = bus.read()
    return sample


def _faulty_actuators(
    config: Config,
    sample: JointSample,
    devices: Sequence[JointDevices],
    reboot_first: bool,
    event: EventLog,
) -> list[int]:
    faulty = []
    for i, joint in enumerate(config.joints):
        actuator = devices[i].actuator
        if not sample.motor_valid[i]:
            errors = "; ".join(str(e) for e in sample.bus_errors)
            raise StartRefused(f"{actuator} ({joint.name}) did not answer the first read: {errors}")
        flags = int(sample.actuator_fault[i])
        if not flags:
            continue
        what = f"{ActuatorFault.describe(flags)} (device code 0x{int(sample.fault_code[i]):02X})"
        if not reboot_first:
            raise StartRefused(
                f"{actuator} ({joint.name}) reports {what}; remove the cause, then run "
                "`hil reboot` or pass --reboot-first"
            )
        event(
            0.0,
            "reboot",
            f"rebooting {actuator} ({joint.name}): it reports {what}",
            joint=joint.name,
        )
        faulty.append(i)
    return faulty


def _reboot(
    config: Config,
    bus: JointBus,
    devices: Sequence[JointDevices],
    faulty: list[int],
    event: EventLog,
) -> JointSample:
    statuses = bus.reboot(faulty)
    event(
        0.0,
        "reboot",
        "after reboot, faults: "
        + ", ".join(f"{name} {ActuatorFault.describe(f)}" for name, f in statuses.items()),
    )
    sample = bus.read()
    for i, joint in enumerate(config.joints):
        if not sample.motor_valid[i] or int(sample.actuator_fault[i]):
            errors = "; ".join(str(e) for e in sample.bus_errors) or "ok"
            raise StartRefused(
                f"{devices[i].actuator} ({joint.name}) still reports "
                f"{ActuatorFault.describe(int(sample.actuator_fault[i]))} after a reboot (or did "
                f"not answer: {errors}): the cause persists (load, temperature, supply voltage?)"
            )
    return sample


def _check_at_rest(config: Config, sample: JointSample, devices: Sequence[JointDevices]) -> None:
    bound = START_DEFLECTION_FACTOR * config.safety.max_deflection_rad
    for i, joint in enumerate(config.joints):
        if not sample.link_valid[i]:
            raise StartRefused(
                f"{devices[i].link_sensor} ({joint.name}) did not answer the first SYNC"
            )
        motor = float(sample.motor_angle_rad[i])
        if not joint.min_angle_rad <= motor <= joint.max_angle_rad:
            raise StartRefused(
                f"joint {joint.name}: the motor stands at {motor:+.4f} rad, outside the joint's "
                f"range [{joint.min_angle_rad:+.3f}, {joint.max_angle_rad:+.3f}] rad: move it "
                "inside by hand (torque is off), or widen the range in the configuration"
            )
        deflection = float(np.asarray(sample.link_angle_rad)[i] - motor)
        if abs(deflection) > bound:
            raise StartRefused(
                f"joint {joint.name}: link minus motor angle is {deflection:+.4f} rad at rest "
                f"(more than {bound} rad): are encoder_offset_rad and motor_offset_rad set?"
            )
