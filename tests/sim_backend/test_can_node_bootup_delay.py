"""An emulated CANopen node restarts like a device: silent for its boot-up delay after an NMT
reset, then the boot-up frame, so that a master's `wait_for_bootup()` after a reset works.

First on a synthetic clock (exact), then with the unmodified `canopen` master over the
emulated SLCAN adapter in another process, many times in a row.
"""

from __future__ import annotations

import time

import can
import canopen
import pytest

from sim_backend.canbus.encoder_node import ENCODER_EDS_FILE, LinkEncoderNode
from sim_backend.canbus.object_store import eds_path
from sim_backend.canbus.slave import DEFAULT_BOOTUP_DELAY_S
from sim_backend.canbus.testing import SyntheticEncoder, serve_segment_in_subprocess

pytestmark = pytest.mark.timeout(120)

NODE = 5
RESET_NODE, RESET_COMMUNICATION, START = 0x81, 0x82, 0x01
REPEATS = 40  # per reset kind; before the delay existed about half of them timed out


def frame(cob_id: int, data: bytes = b"") -> can.Message:
    return can.Message(arbitration_id=cob_id, is_extended_id=False, data=data)


def sdo_read_device_type() -> can.Message:
    return frame(0x600 + NODE, bytes((0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0)))


def started_node(delay_s: float) -> LinkEncoderNode:
    node = LinkEncoderNode(NODE, lambda: 0.1, heartbeat_ms=10, bootup_delay_s=delay_s)
    assert [bytes(m.data) for m in node.poll(0.0)] == [b"\x00"]  # power-on boot-up
    node.handle(frame(0x000, bytes((START, NODE))), 0.0)
    assert node.nmt_state == 0x05
    return node


@pytest.mark.parametrize("command", [RESET_NODE, RESET_COMMUNICATION])
def test_after_a_reset_the_node_is_silent_for_its_delay_then_boots(command: int) -> None:
    delay_s = 0.004
    node = started_node(delay_s)
    assert node.handle(frame(0x000, bytes((command, 0))), 1.0) == []  # no boot-up with it
    assert node.booting and node.nmt_state == 0x00
    assert node.next_due_s() == pytest.approx(1.0 + delay_s)
    # Initialising: deaf to SDO, SYNC and NMT, and no heartbeat (10 ms would be due).
    for t_s in (1.001, 1.002, 1.0039):
        assert node.handle(sdo_read_device_type(), t_s) == []
        assert node.handle(frame(0x080), t_s) == []
        assert node.handle(frame(0x000, bytes((START, NODE))), t_s) == []
        assert node.poll(t_s) == []
    booted = node.poll(1.0 + delay_s)
    assert [(m.arbitration_id, bytes(m.data)) for m in booted] == [(0x705, b"\x00")]
    assert not node.booting and node.nmt_state == 0x7F
    answer = node.handle(sdo_read_device_type(), 1.0 + delay_s)
    assert [bytes(m.data)[4:] for m in answer] == [(0x0002_0196).to_bytes(4, "little")]


def test_the_boot_up_goes_out_with_the_first_frame_handled_after_the_delay() -> None:
    node = started_node(0.004)
    node.handle(frame(0x000, bytes((RESET_COMMUNICATION, NODE))), 2.0)
    replies = node.handle(sdo_read_device_type(), 2.005)  # booted by now: boot-up, then answer
    assert [m.arbitration_id for m in replies] == [0x705, 0x585]
    assert bytes(replies[0].data) == b"\x00"


def test_a_dead_node_whose_power_returns_boots_after_the_delay() -> None:
    node = started_node(0.003)
    node.fault.mode = "dead"
    assert node.poll(1.0) == [] and node.next_due_s() is None
    node.fault.mode = "ok"
    assert node.poll(1.001) == [] and node.booting
    assert [bytes(m.data) for m in node.poll(1.004)] == [b"\x00"]


def test_zero_delay_boots_in_the_reply_to_the_command_and_bad_delays_are_refused() -> None:
    node = started_node(0.0)
    replies = node.handle(frame(0x000, bytes((RESET_NODE, NODE))), 1.0)
    assert [(m.arbitration_id, bytes(m.data)) for m in replies] == [(0x705, b"\x00")]
    for bad in (-0.001, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="bootup_delay_s"):
            LinkEncoderNode(NODE, lambda: 0.0, bootup_delay_s=bad)
    assert DEFAULT_BOOTUP_DELAY_S > 0.0


def test_canopen_wait_for_bootup_after_every_reset_over_the_slcan_pty() -> None:
    """The master resets the node and then waits for its boot-up, REPEATS times per kind."""
    with serve_segment_in_subprocess([SyntheticEncoder(NODE, angle_rad=0.2)]) as served:
        network = canopen.Network(can.Bus(**served.bus_kwargs))
        network.connect()
        try:
            remote = network.add_node(NODE, str(eds_path(ENCODER_EDS_FILE)))
            waited_s: list[float] = []
            for command in (RESET_COMMUNICATION, RESET_NODE) * REPEATS:
                remote.nmt.send_command(command)
                started = time.perf_counter()
                remote.nmt.wait_for_bootup(timeout=2.0)  # raises NmtError on a timeout
                waited_s.append(time.perf_counter() - started)
                assert remote.sdo[0x1000].raw == 0x0002_0196  # it answers after booting
        finally:
            network.disconnect()
    waited_s.sort()
    print(
        f"\nwait_for_bootup after {len(waited_s)} resets: median "
        f"{waited_s[len(waited_s) // 2] * 1e3:.1f} ms, max {waited_s[-1] * 1e3:.1f} ms"
    )
    assert len(waited_s) == 2 * REPEATS
