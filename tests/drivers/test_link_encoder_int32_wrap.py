"""The link encoder's INTEGER32 position at its wrap, on the wire: a preset written by SDO
just below 2**31 - 1, a few counts of motion, the two's-complement wrap in the TPDO (at 2**32,
not 2**31), and the driver reading on through it (the count's difference taken modulo 2**32:
a link never turns 2**31 counts, 2184 revolutions, between two readings)."""

from __future__ import annotations

import math
import struct

import can
import canopen
import pytest

from drivers.canbus import LinkEncoderConfig
from sim_backend.canbus import LinkEncoderNode
from tests.support.can_rig import Rig

pytestmark = pytest.mark.timeout(30)

N = 983_040
COUNT_RAD = 2 * math.pi / N
NODE = 5
PRESET = 2**31 - 3  # three counts below the largest INTEGER32


def _sdo(rig: Rig, action) -> object:
    """A canopen client of our own on the rig's channel (not the driver) does `action`."""
    network = canopen.Network()
    network.connect(interface="virtual", channel=rig.channel)
    try:
        remote = canopen.RemoteNode(NODE, canopen.ObjectDictionary())
        network.add_node(remote)
        found: list[object] = []
        rig.serve_while(lambda: found.append(action(remote)))
        return found[0]
    finally:
        network.disconnect()


def _tpdo_counts(sniffer: can.BusABC) -> int:
    """The position in the node's last TPDO1 frame (0x180 + node ID), as sent."""
    frames = []
    while (frame := sniffer.recv(timeout=0)) is not None:
        if frame.arbitration_id == 0x180 + NODE:
            frames.append(frame)
    assert frames, "no TPDO"
    return struct.unpack_from("<i", bytes(frames[-1].data))[0]


def test_the_position_wraps_at_2_to_the_32_and_the_driver_reads_on_through_it() -> None:
    angle = [0.0]
    node = LinkEncoderNode(NODE, lambda: angle[0])
    offset_rad = PRESET * COUNT_RAD  # the encoder's reading at the link's zero
    rig = Rig([node], [LinkEncoderConfig(NODE, offset_rad=offset_rad, name="link")])
    sniffer = can.Bus(interface="virtual", channel=rig.channel)
    try:
        _sdo(rig, lambda r: r.sdo.download(0x6003, 0, struct.pack("<i", PRESET)))
        read_back = _sdo(rig, lambda r: struct.unpack("<i", r.sdo.upload(0x6004, 0))[0])
        assert read_back == PRESET
        rig.open()

        first = rig.tick()
        assert _tpdo_counts(sniffer) == PRESET
        assert first.angles_rad[0] == pytest.approx(0.0, abs=1e-9)

        angle[0] = 5 * COUNT_RAD  # five counts on: 2**31 + 2, which an INTEGER32 holds as
        wrapped = rig.tick()  # -2**31 + 2 (two's complement at 2**32)
        assert _tpdo_counts(sniffer) == -(2**31) + 2
        assert wrapped.angles_rad[0] == pytest.approx(5 * COUNT_RAD, abs=1e-9)

        angle[0] = -5 * COUNT_RAD  # and back through the wrap
        back = rig.tick()
        assert _tpdo_counts(sniffer) == PRESET - 5
        assert back.angles_rad[0] == pytest.approx(-5 * COUNT_RAD, abs=1e-9)
    finally:
        sniffer.shutdown()
        rig.close()
