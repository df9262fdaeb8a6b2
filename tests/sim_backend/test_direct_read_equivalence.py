"""The in-process emulated robot's whole-robot read (`DirectTestbed.read`: the Present* blocks
of every device unpacked at once, the counts converted on arrays) and goal write (`write_goals`)
against the joint-by-joint reference they replaced: per joint, the actuator's Present Position,
Velocity and Current items converted and its mounting undone, the link encoder's count
converted, one Goal Position WRITE per joint. Two robots from one spec (the same seeds) side
by side, with actuators and encoders mounted at random and every kind of fault in its window:
every reading and every byte of every control table must be equal, not close."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from hil.config import load_config
from hil.wiring.emulation import emulator_spec
from sim_backend.direct import DirectReading, DirectTestbed
from sim_backend.dynamixel.control_table import H54_LAYOUT
from sim_backend.scenario import FaultEvent
from sim_backend.servo import AMPERE_PER_CURRENT_UNIT, RAD_PER_PULSE, RAD_S_PER_VELOCITY_UNIT

FAULTS = (
    FaultEvent("silent_id", 0.05, 0.05, joint=3),
    FaultEvent("dropped_reply", 0.08, joint=5),
    FaultEvent("corrupt_crc", 0.12, 0.03, joint=7),
    FaultEvent("dead_encoder", 0.10, 0.08, joint=2),
    FaultEvent("noisy_encoder", 0.15, 0.10, joint=9, noise_counts_rms=3.0),
    FaultEvent("stale_encoder", 0.20, 0.05, joint=0),
)


def reference_read(testbed: DirectTestbed) -> DirectReading:
    """The joint-by-joint read (what `DirectTestbed.read` did before its block path)."""
    n = testbed.n_joints
    nan = np.full(n, np.nan)
    reading = DirectReading(
        nan.copy(), nan.copy(), nan.copy(), np.zeros(n, dtype=np.uint8),
        np.zeros(n, dtype=bool), np.zeros(n, dtype=bool), nan.copy(),
        np.zeros(n, dtype=bool), testbed._force_n(),
        [node.sample_wrench(testbed.time_s) for node in testbed.ft_sensors],
    )  # fmt: skip
    for i in range(n):
        if testbed._actuator_answers(i):
            device, mount = testbed.robot.devices[i], testbed.robot.mountings[i]
            pulses = device.item("Present Position")
            reading.motor_angle_rad[i] = mount.to_physical(pulses * RAD_PER_PULSE)
            velocity = device.item("Present Velocity") * RAD_S_PER_VELOCITY_UNIT
            reading.motor_velocity_rad_s[i] = mount.direction * velocity
            current = device.item("Present Current") * AMPERE_PER_CURRENT_UNIT
            reading.motor_current_a[i] = mount.direction * current
            reading.hardware_error[i] = device.hardware_error_status
            reading.torque_enabled[i] = device.torque_enabled
            reading.motor_valid[i] = True
        counts = testbed.encoders[i].sample(testbed.time_s)
        if counts is not None:
            joint = testbed.spec.joints[i]
            angle = counts / (joint.encoder_counts_per_rev / (2.0 * math.pi))
            reading.link_angle_rad[i] = joint.encoder_direction * (angle - joint.encoder_offset_rad)
            reading.link_valid[i] = True
    return reading


def assert_same(got: DirectReading, expected: DirectReading) -> None:
    for field in dataclasses.fields(DirectReading):
        a, b = getattr(got, field.name), getattr(expected, field.name)
        if field.name == "wrenches":
            for wrench_a, wrench_b in zip(a, b, strict=True):
                assert (wrench_a is None) == (wrench_b is None)
                if wrench_a is not None:
                    for part_a, part_b in zip(wrench_a, wrench_b, strict=True):
                        np.testing.assert_array_equal(part_a, part_b)
        elif isinstance(a, np.ndarray):
            assert a.dtype == b.dtype, field.name
            np.testing.assert_array_equal(a, b, err_msg=field.name)  # NaN equals NaN
        else:
            assert a == b or (math.isnan(a) and math.isnan(b)), field.name


@pytest.mark.parametrize("robot", ["dyros-jet", "testbed"])
def test_the_block_read_and_write_equal_the_per_joint_ones(robot: str) -> None:
    config = load_config(robot=robot) if robot != "testbed" else load_config()
    rng = np.random.default_rng(4)
    faults = FAULTS
    if robot == "testbed":  # one joint: every fault on it
        faults = tuple(dataclasses.replace(fault, joint=0) for fault in FAULTS)
    spec = emulator_spec(config, faults=faults)
    joints = tuple(
        dataclasses.replace(
            joint,
            motor_direction=int(rng.choice([1, -1])),
            motor_offset_rad=float(rng.uniform(-0.3, 0.3)),
            encoder_direction=int(rng.choice([1, -1])),
            encoder_offset_rad=float(rng.uniform(-0.3, 0.3)),
        )
        for joint in spec.joints
    )
    spec = dataclasses.replace(spec, joints=joints)
    block, reference = DirectTestbed(spec), DirectTestbed(spec)
    n = block.n_joints
    for testbed in (block, reference):
        for i in range(n):
            assert testbed.set_torque(i, True)
    refused = 0
    for tick in range(60):
        block.sync()
        reference.sync()
        got, expected = block.read(), reference_read(reference)
        assert_same(got, expected)
        goals = np.nan_to_num(expected.motor_angle_rad) + rng.normal(0, 0.02, n)
        if tick % 7 == 3:
            goals[-1] = 50.0  # beyond the position limits: refused by the device, both ways
        written = block.write_goals(goals)
        assert written == [reference.write_goal(i, float(goals[i])) for i in range(n)]
        refused += written.count(False)
        for a, b in zip(block.robot.devices, reference.robot.devices, strict=True):
            assert a.read(0, H54_LAYOUT.size_bytes) == b.read(0, H54_LAYOUT.size_bytes)
    assert all(block.schedule.fired)  # every fault acted
    assert refused > 0  # and a goal was refused (or not heard)
