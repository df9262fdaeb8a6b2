"""The lock-step emulator answers a Dynamixel read that came with the SYNC after the SYNC has
stepped the plant and before the SYNC's TPDOs are sent (the host parses the status packets
while the CAN frames are written); a read that comes later is still answered after the step.
The host's bytes go into the real ptys; the two writes are recorded in order."""

from __future__ import annotations

import struct

import can
import pytest
import serial

from sim_backend.dynamixel.control_table import H54_LAYOUT
from sim_backend.dynamixel.protocol import Instruction, build_instruction_packet
from sim_backend.server import EmulatedJointSpec, Emulator, EmulatorSpec

SYNC = can.Message(arbitration_id=0x080, data=b"", is_extended_id=False)
PRESENT_POSITION = H54_LAYOUT["Present Position"]


def _sync_read_packet(dxl_id: int) -> bytes:
    params = struct.pack("<HH", PRESENT_POSITION.address, PRESENT_POSITION.size) + bytes([dxl_id])
    return build_instruction_packet(0xFE, Instruction.SYNC_READ, params)


@pytest.fixture
def emulator():
    emulator = Emulator(
        EmulatorSpec(joints=(EmulatedJointSpec(dxl_id=1, encoder_node_id=5),), clock="lockstep")
    )
    yield emulator
    emulator.close()


def _record_writes(emulator: Emulator) -> list[tuple[str, float]]:
    """(which bus, the plant's time) for each write the emulator makes from now on."""
    writes: list[tuple[str, float]] = []
    line_write, send_frames = emulator.line._write, emulator.slcan.send_frames

    def on_line(packets: list[bytes]) -> None:
        writes.append(("dynamixel", emulator.testbed.time_s))
        line_write(packets)

    def on_can(frames) -> None:  # type: ignore[no-untyped-def]
        frames = list(frames)
        if frames:
            writes.append(("can", emulator.testbed.time_s))
        send_frames(frames)

    emulator.line._write = on_line  # type: ignore[method-assign]
    emulator.slcan.send_frames = on_can  # type: ignore[method-assign]
    return writes


def _host_writes_line(emulator: Emulator, data: bytes) -> None:
    """As the host's SDK does: the port at the chain's baud rate (the emulated devices ignore
    bytes at another rate), then the packet."""
    with serial.Serial(emulator.line.port_path, baudrate=emulator.spec.baudrate) as port:
        port.write(data)


def test_a_read_sent_with_the_sync_is_answered_after_the_step_before_the_tpdos(emulator) -> None:
    emulator._on_host_frames([SYNC])  # t = 0: the first SYNC samples, nothing steps
    emulator.segment.deliver(
        can.Message(arbitration_id=0x000, data=bytes([0x01, 0]), is_extended_id=False), 0.0
    )  # NMT start: the encoder answers SYNCs with its TPDO from now on
    writes = _record_writes(emulator)
    _host_writes_line(emulator, _sync_read_packet(1))
    emulator._on_host_frames([SYNC])
    period = emulator.spec.period_s
    assert [bus for bus, _ in writes] == ["dynamixel", "can"]
    assert writes[0][1] == pytest.approx(period)  # answered with the stepped plant's state


def test_a_read_not_there_at_the_sync_is_answered_in_the_loops_next_turn(emulator) -> None:
    emulator._on_host_frames([SYNC])
    writes = _record_writes(emulator)
    emulator._on_host_frames([SYNC])
    assert [bus for bus, _ in writes if bus == "dynamixel"] == []
    _host_writes_line(emulator, _sync_read_packet(1))
    emulator.line.on_readable()
    assert emulator.line.holds_reads  # held until the CAN side is served, as before
    emulator.line.release_held_reads()
    assert writes[-1] == ("dynamixel", pytest.approx(emulator.spec.period_s))
