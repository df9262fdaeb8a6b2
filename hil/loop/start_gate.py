"""The start gate: tick 0 decides whether torque may go on, before anything moves.

Refused (`StartRefused`, nothing was moved) when, after up to START_READ_ATTEMPTS reads:
    an actuator did not answer, or reports a fault (with --reboot-first: it is rebooted and
    read again; a fault that persists is refused);
    a link sensor did not answer;
    a motor stands outside its joint's range;
    a joint's link and motor angles disagree at rest by more than [safety]
    zero_offset_margin_rad: the zero offsets (motor_offset_rad, encoder_offset_rad) are wrong,
    and the message says what each would have to be (`hil calibrate` measures them).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from drivers.joint_bus import ActuatorFault, JointBus, JointDevices, JointSample
from hil.config import Config

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
        link = float(np.asarray(sample.link_angle_rad)[i])
        check_zero_offsets(config, i, motor, link)


def check_zero_offsets(config: Config, joint_index: int, motor_rad: float, link_rad: float) -> None:
    """Refuse when the link and motor angles at rest disagree by more than the margin; the
    message names the keys and the value each would need (if the other one is right)."""
    joint = config.joints[joint_index]
    margin = config.safety.zero_offset_margin_rad
    deflection = link_rad - motor_rad
    if abs(deflection) <= margin:
        return
    # link = d_e (r_e - o_e): o_e + d_e * deflection makes the link read the motor's angle;
    # motor = d_m (r_m - o_m): o_m - d_m * deflection makes the motor read the link's.
    encoder_fix = joint.encoder_offset_rad + joint.encoder_direction * deflection
    motor_fix = joint.motor_offset_rad - joint.motor_direction * deflection
    raise StartRefused(
        f"joint {joint.name}: at rest the link reads {link_rad:+.4f} rad and the motor "
        f"{motor_rad:+.4f} rad; they disagree by {deflection:+.4f} rad, more than [safety] "
        f"zero_offset_margin_rad = {margin} rad: the zero offsets are wrong. Hold the robot at "
        "its reference pose and run `hil calibrate` (it prints both offsets), or fix "
        f"[[joint]] {joint.name!r} encoder_offset_rad (= {encoder_fix:.6f} if the motor's zero "
        f"is right) or motor_offset_rad (= {motor_fix:.6f} if the link encoder's is right)"
    )
