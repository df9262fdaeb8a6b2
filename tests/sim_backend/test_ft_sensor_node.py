"""The emulated six-axis force/torque node (CiA 404, two TPDOs) as a pure frame handler."""

from __future__ import annotations

import struct

import can
import numpy as np
import pytest

from sim_backend.canbus.ft_sensor_node import ForceTorqueSensorNode

NODE = 21


def frame(cob_id: int, data: bytes) -> can.Message:
    return can.Message(arbitration_id=cob_id, data=data, is_extended_id=False)


def sdo_upload(node: ForceTorqueSensorNode, index: int, sub: int) -> bytes:
    request = bytes([0x40, index & 0xFF, index >> 8, sub, 0, 0, 0, 0])
    (reply,) = node.handle(frame(0x600 + NODE, request), 0.0)
    assert reply.data[0] & 0xE0 == 0x40, f"abort {reply.data.hex()}"
    return bytes(reply.data[4:8])


def sdo_download(node: ForceTorqueSensorNode, index: int, sub: int, value: int) -> bytes:
    request = bytes([0x2F, index & 0xFF, index >> 8, sub, value & 0xFF, 0, 0, 0])
    (reply,) = node.handle(frame(0x600 + NODE, request), 0.0)
    return bytes(reply.data)


class CountingSource:
    def __init__(self) -> None:
        self.calls = 0
        self.force = np.array([1.0, 2.0, 3.0])
        self.torque = np.array([0.1, 0.2, 0.3])

    def __call__(self) -> tuple[np.ndarray, np.ndarray]:
        self.calls += 1
        return self.force + self.calls, self.torque  # a different value at every call


@pytest.fixture
def node() -> tuple[ForceTorqueSensorNode, CountingSource]:
    source = CountingSource()
    sensor = ForceTorqueSensorNode(NODE, source)
    sensor.poll(0.0)  # boot-up
    sensor.handle(frame(0x000, bytes([0x01, NODE])), 0.0)  # NMT start
    return sensor, source


def test_object_dictionary(node) -> None:
    sensor, _ = node
    assert struct.unpack("<I", sdo_upload(sensor, 0x1000, 0))[0] == 0x00020194
    assert sdo_upload(sensor, 0x6131, 0)[0] == 6
    units = [struct.unpack("<I", sdo_upload(sensor, 0x6131, ch))[0] for ch in range(1, 7)]
    assert units == [0x00210000] * 3 + [0x00230000] * 3
    digits = [sdo_upload(sensor, 0x6132, ch)[0] for ch in range(1, 7)]
    assert digits == [1, 1, 1, 2, 2, 2]
    mapping = [struct.unpack("<I", sdo_upload(sensor, 0x1A01, e))[0] for e in (1, 2, 3)]
    assert mapping == [0x71300410, 0x71300510, 0x71300610]


def test_one_sample_feeds_both_tpdos(node) -> None:
    sensor, source = node
    frames = sensor.handle(frame(0x080, b""), 0.005)
    assert [f.arbitration_id for f in frames] == [0x180 + NODE, 0x280 + NODE]
    assert source.calls == 1
    forces = struct.unpack("<hhh", frames[0].data)
    moments = struct.unpack("<hhh", frames[1].data)
    assert forces == (20, 30, 40)  # (1+1, 2+1, 3+1) N in 0.1 N
    assert moments == (10, 20, 30)  # 0.01 N m per count


def test_tpdo2_takes_sync_types_only(node) -> None:
    sensor, _ = node
    refused = sdo_download(sensor, 0x1801, 2, 254)
    assert refused[0] == 0x80 and struct.unpack("<I", refused[4:8])[0] == 0x06090030
    sdo_download(sensor, 0x1801, 2, 2)  # every second SYNC
    ids = [[f.arbitration_id for f in sensor.handle(frame(0x080, b""), k * 0.005)] for k in (1, 2)]
    assert ids == [[0x180 + NODE], [0x180 + NODE, 0x280 + NODE]]


def test_noisy_channels_are_deterministic() -> None:
    def make() -> ForceTorqueSensorNode:
        sensor = ForceTorqueSensorNode(NODE, lambda: (np.zeros(3), np.zeros(3)), seed=7)
        sensor.poll(0.0)
        sensor.handle(frame(0x000, bytes([0x01, NODE])), 0.0)
        sensor.fault.mode = "noisy"
        sensor.fault.noise_counts_rms = 20.0
        return sensor

    runs = [
        [bytes(f.data) for k in range(20) for f in make_node.handle(frame(0x080, b""), k * 0.005)]
        for make_node in (make(), make())
    ]
    assert runs[0] == runs[1]
    values = np.array([struct.unpack("<hhh", data) for data in runs[0]], dtype=float)
    assert 10 < values.std() < 30
