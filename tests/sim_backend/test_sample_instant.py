"""The realtime emulator's link encoders latch at the SYNC's instant, not at the last physics
step: reading = angle + velocity * (time since the step), checked against that formula on a
moving link, and the server's instant stays within [0, one step]."""

from __future__ import annotations

import math
import struct
import time

import can
import pytest

from sim_backend.hardware import EmulatedTestbed
from sim_backend.server import EmulatedJointSpec, Emulator, EmulatorSpec, SensorNoise

SYNC = can.Message(arbitration_id=0x080, data=b"", is_extended_id=False)
START_ALL = can.Message(arbitration_id=0x000, data=bytes([0x01, 0]), is_extended_id=False)
NODE = 5
COUNTS_PER_RAD = 983_040 / (2 * math.pi)


def _spec(clock: str = "lockstep") -> EmulatorSpec:
    return EmulatorSpec(
        joints=(EmulatedJointSpec(dxl_id=1, encoder_node_id=NODE),),
        sensor_noise=SensorNoise(link_encoder_counts_rms=0.0),
        clock=clock,
    )


def _latched_rad(hardware: EmulatedTestbed) -> float:
    node = hardware.encoders[0]
    node.poll(0.0)
    node.handle(START_ALL, 0.0)
    frames = node.handle(SYNC, 0.001)
    tpdo = next(f for f in frames if f.arbitration_id == 0x180 + NODE)
    return struct.unpack("<i", bytes(tpdo.data[:4]))[0] / COUNTS_PER_RAD


def test_encoder_latches_angle_plus_velocity_times_the_time_past_the_step() -> None:
    hardware = EmulatedTestbed.build(_spec())
    plant = hardware.joints[0].plant
    plant.data.qvel[:] = 0.8  # rad/s on every DoF: the link moves at 1.6 rad/s
    angle, velocity = plant.link_angle_rad, plant.link_velocity_rad_s
    assert abs(velocity) > 1.0
    at_step = _latched_rad(hardware)
    hardware.sample_instant.after_step_s = 0.7e-3
    later = _latched_rad(hardware)
    quantum = 1 / COUNTS_PER_RAD
    assert at_step == pytest.approx(angle, abs=quantum)
    assert later == pytest.approx(angle + velocity * 0.7e-3, abs=quantum)
    assert abs(later - at_step) > 100 * quantum  # the test can tell the two apart


def test_server_sets_the_instant_within_one_step_in_realtime_only() -> None:
    for clock in ("realtime", "lockstep"):
        emulator = Emulator(_spec(clock))
        try:
            emulator._on_sync()  # the first SYNC: the scenario starts
            time.sleep(0.003)  # the plant is not stepped meanwhile: more than a step behind
            emulator._on_sync()
            instant = emulator.hardware.sample_instant.after_step_s
            step = emulator.testbed.physics_timestep_s
            if clock == "realtime":
                assert instant == pytest.approx(step)  # capped at one step
            else:
                assert instant == 0.0
        finally:
            emulator.close()
