"""Robustness of the emulated H54 line against a real client (unmodified dynamixel-sdk):
garbage on the line, truncated packets, baud mismatch, injected line faults.
"""

from __future__ import annotations

import random
import time
from collections.abc import Callable, Iterator
from functools import partial

import pytest
from dynamixel_sdk import (
    COMM_RX_CORRUPT,
    COMM_RX_TIMEOUT,
    COMM_SUCCESS,
    GroupSyncRead,
    PacketHandler,
)

from sim_backend.dynamixel.protocol import HEADER, Instruction, build_instruction_packet
from sim_backend.dynamixel.testing import EmulatedChain, spawn_emulated_chain
from tests.support.load_conditions import PatientPortHandler

pytestmark = pytest.mark.timeout(60)

MODEL_H54 = 54024
TABLE_BYTES = 893
LED_ADDRS = (563, 564, 565)
GOAL_POSITION_ADDR = 596
IDS = (1, 2, 3)
FOREIGN_ID = 200  # an ID nobody on the line has


class Bus:
    def __init__(self, emu: EmulatedChain, baud: int = 4_000_000) -> None:
        self.emu = emu
        self.port = PatientPortHandler(emu.port_path)
        self.ph = PacketHandler(2.0)
        assert self.port.openPort()
        assert self.port.setBaudRate(baud)

    def close(self) -> None:
        self.port.closePort()


@pytest.fixture
def bus() -> Iterator[Bus]:
    with spawn_emulated_chain(ids=IDS, baud_index=6) as emu:
        handle = Bus(emu)
        yield handle
        handle.close()


def table_snapshot(bus: Bus, dxl_id: int) -> bytes:
    data, comm, error = bus.ph.readTxRx(bus.port, dxl_id, 0, TABLE_BYTES)
    assert (comm, error) == (COMM_SUCCESS, 0)
    return bytes(data)


def biased_garbage(rng: random.Random, length: int) -> bytes:
    """Random bytes rich in FF/FD/00 so that header-like sequences are frequent. Any
    FF FF FD 00 it contains is addressed to FOREIGN_ID, so no CRC-error status from our IDs
    can race the SDK's next request (that is tested separately, with a pause)."""
    alphabet = (0xFF, 0xFF, 0xFF, 0xFD, 0xFD, 0x00, 0x00)
    data = bytearray(
        rng.choice(alphabet) if rng.random() < 0.6 else rng.randrange(256) for _ in range(length)
    )
    start = data.find(HEADER + b"\x00")
    while 0 <= start < len(data) - 4:
        data[start + 4] = FOREIGN_ID
        start = data.find(HEADER + b"\x00", start + 1)
    if data.endswith(HEADER + b"\x00"):
        data += bytes((FOREIGN_ID,))
    return bytes(data)


def corrupted_write(rng: random.Random) -> bytes:
    """A WRITE to one of our IDs with a wrong CRC: must be answered with CRC Error, not run."""
    dxl_id = rng.choice(IDS)
    params = rng.choice(LED_ADDRS).to_bytes(2, "little") + bytes((rng.randrange(256),))
    frame = bytearray(build_instruction_packet(dxl_id, Instruction.WRITE, params))
    frame[-2] ^= 1 + rng.randrange(255)
    return bytes(frame)


def byte_timeouts_exceed(emu: EmulatedChain, count: int) -> bool:
    return emu.stats()["byte_timeouts"] > count


def wait_until(condition: Callable[[], bool], timeout_s: float = 5.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, "emulator did not get there in time"
        time.sleep(0.001)


def test_seeded_garbage_never_corrupts_the_table_and_every_request_is_answered(bus: Bus) -> None:
    ph, port = bus.ph, bus.port
    before = {dxl_id: bytearray(table_snapshot(bus, dxl_id)) for dxl_id in IDS}
    rng = random.Random(20240611)
    expected_led = {(dxl_id, addr): 0 for dxl_id in IDS for addr in LED_ADDRS}
    for round_index in range(80):
        if round_index % 4 == 3:
            # corrupted writes to our IDs and a truncated packet, then a pause: the CRC-error
            # statuses arrive and are flushed by the SDK's next request
            junk = corrupted_write(rng) + biased_garbage(rng, 20) + corrupted_write(rng)
            junk += build_instruction_packet(1, Instruction.READ, b"\x63\x02\x04\x00")[:9]
            timeouts_before = bus.emu.stats()["byte_timeouts"]
            port.writePort(junk)
            # the trailing fragment is dropped only after everything before it was answered
            wait_until(partial(byte_timeouts_exceed, bus.emu, timeouts_before))
        else:
            port.writePort(biased_garbage(rng, rng.randrange(1, 200)))  # then at once a request
        dxl_id = rng.choice(IDS)
        action = rng.randrange(4)
        if action == 0:
            assert ph.ping(port, dxl_id) == (MODEL_H54, COMM_SUCCESS, 0)
        elif action == 1:
            addr = rng.choice(LED_ADDRS)
            value = rng.randrange(256)
            assert ph.write1ByteTxRx(port, dxl_id, addr, value) == (COMM_SUCCESS, 0)
            expected_led[(dxl_id, addr)] = value
        elif action == 2:
            addr = rng.choice(LED_ADDRS)
            assert ph.read1ByteTxRx(port, dxl_id, addr) == (
                expected_led[(dxl_id, addr)],
                COMM_SUCCESS,
                0,
            )
        else:
            reader = GroupSyncRead(port, ph, 563, 3)
            for i in IDS:
                reader.addParam(i)
            assert reader.txRxPacket() == COMM_SUCCESS
            for i in IDS:
                for addr in LED_ADDRS:
                    assert reader.getData(i, addr, 1) == expected_led[(i, addr)]
    time.sleep(0.01)
    for dxl_id in IDS:
        for addr in LED_ADDRS:
            before[dxl_id][addr] = expected_led[(dxl_id, addr)]
        assert table_snapshot(bus, dxl_id) == bytes(before[dxl_id])
    stats = bus.emu.stats()
    assert stats["crc_errors"] >= 20  # the corrupted writes were seen and refused
    assert stats["discarded_bytes"] > 1000
    assert stats["byte_timeouts"] >= 20  # each truncated READ was dropped after idle


@pytest.mark.parametrize("realtime", [False, True], ids=["instant", "realtime"])
def test_truncated_packet_then_idle_is_dropped(realtime: bool) -> None:
    with spawn_emulated_chain(ids=(1,), baud_index=6, realtime=realtime) as emu:
        bus = Bus(emu)
        read = build_instruction_packet(1, Instruction.READ, b"\x63\x02\x04\x00")
        bus.port.writePort(read[:8])
        # The line stays idle until the emulator itself has timed the fragment out (its own
        # counter; a fixed sleep assumed it would be scheduled within 10 ms)
        wait_until(partial(byte_timeouts_exceed, emu, 0))
        # had the fragment been kept, the ping would complete it into a frame with a bad CRC
        # and the SDK would get a CRC-error status from ID 1
        assert bus.ph.ping(bus.port, 1) == (MODEL_H54, COMM_SUCCESS, 0)
        stats = emu.stats()
        assert stats["byte_timeouts"] >= 1 and stats["crc_errors"] == 0
        bus.close()


def test_enforce_baud_device_is_silent_at_another_speed() -> None:
    with spawn_emulated_chain(ids=(1,), baud_index=6, enforce_baud=True) as emu:
        bus = Bus(emu, baud=1_000_000)
        ph, port = bus.ph, bus.port
        assert ph.ping(port, 1)[1] == COMM_RX_TIMEOUT  # device at 4 Mbps hears garbage
        assert port.setBaudRate(4_000_000)
        assert ph.ping(port, 1) == (MODEL_H54, COMM_SUCCESS, 0)
        assert ph.write1ByteTxRx(port, 1, 8, 3) == (COMM_SUCCESS, 0)  # Baud Rate := 1 Mbps
        assert ph.ping(port, 1)[1] == COMM_RX_TIMEOUT
        assert port.setBaudRate(1_000_000)
        assert ph.ping(port, 1) == (MODEL_H54, COMM_SUCCESS, 0)
        bus.close()


def test_line_faults_through_the_sdk(bus: Bus) -> None:
    ph, port = bus.ph, bus.port
    bus.emu.faults(drop_reply_ids={1})
    assert ph.write1ByteTxRx(port, 1, 563, 9)[0] == COMM_RX_TIMEOUT
    bus.emu.faults(drop_reply_ids=set())
    assert ph.read1ByteTxRx(port, 1, 563)[:2] == (9, COMM_SUCCESS)  # it was executed
    bus.emu.faults(corrupt_crc_ids={2})
    assert ph.ping(port, 2)[1] == COMM_RX_CORRUPT
    bus.emu.clear_faults()
    bus.emu.faults(corrupt_next_replies=1)
    assert ph.ping(port, 3)[1] == COMM_RX_CORRUPT
    assert ph.ping(port, 3)[1] == COMM_SUCCESS
    bus.emu.faults(drop_next_replies=1)
    assert ph.ping(port, 3)[1] == COMM_RX_TIMEOUT
    assert ph.ping(port, 3)[1] == COMM_SUCCESS
    bus.emu.faults(silent_ids={3})
    assert ph.write1ByteTxRx(port, 3, 563, 5)[0] == COMM_RX_TIMEOUT
    bus.emu.clear_faults()
    assert ph.read1ByteTxRx(port, 3, 563)[:2] == (0, COMM_SUCCESS)  # unplugged: not executed
    bus.emu.set_silenced(2)
    assert ph.ping(port, 2)[1] == COMM_RX_TIMEOUT
    bus.emu.set_silenced(2, False)
    assert ph.ping(port, 2)[1] == COMM_SUCCESS
