"""Property-based fuzzing of the emulator's Protocol 2.0 receive path (hypothesis).

Layers under test: `PacketParser` (framing, CRC, byte timeout), `DynamixelChain.handle` above it
(instruction semantics), and `DynamixelLine` on a real pty. Inputs: arbitrary bytes, valid
instruction packets with corruption (byte flips, insertions, deletions, truncation), all split
at arbitrary points with arbitrary gaps. Properties:

- nothing raises, and the parser's buffer stays bounded (it never waits on a frame forever);
- the parser never invents a packet: every frame it reports as CRC-good is a substring of
  the input that frames exactly that packet;
- how the bytes are split does not change what is parsed (gaps shorter than the byte timeout);
- after garbage and an idle line (> 1.5 ms, the e-Manual's byte timeout) a valid packet is
  parsed, executed and answered exactly;
- garbage never changes a control table: the tables equal those of a twin chain that ran only
  the CRC-good packets the parser found.

Case counts: `max_examples` below, times FUZZ_SCALE (environment, default 1). The long run:
    FUZZ_SCALE=50 .venv/bin/pytest -q --timeout=0 tests/sim_backend/test_fuzz_dxl_emulator_parser.py
"""

from __future__ import annotations

import os
import select
import tty

import pytest
from dynamixel_sdk import PacketHandler
from hypothesis import given
from hypothesis import strategies as st

from sim_backend.dynamixel.chain import DynamixelChain
from sim_backend.dynamixel.control_table import TABLE_SIZE_BYTES
from sim_backend.dynamixel.device import H54Device
from sim_backend.dynamixel.line import DynamixelLine
from sim_backend.dynamixel.protocol import (
    BYTE_TIMEOUT_S,
    HEADER,
    MAX_PACKET_BYTES,
    ErrorCode,
    Instruction,
    PacketParser,
    ParsedPacket,
    build_instruction_packet,
    parse_packet,
)
from tests.support.fuzzing import examples

IDS = (1, 2)
LED_RED = 563  # RAM, 1 byte, 0..255: a write any test can check
IDLE_S = 2 * BYTE_TIMEOUT_S
SDK = PacketHandler(2.0)  # an independent CRC and unstuffing, for the oracle

pytestmark = pytest.mark.timeout(120)


# --- strategies ------------------------------------------------------------------------------

# Bytes rich in the header's values, so that header-like sequences are frequent.
protocol_bytes = st.one_of(
    st.sampled_from([0xFF, 0xFD, 0x00, 0x55, 0x01, 0x02, 0xFE]), st.integers(0, 255)
)
garbage = st.lists(protocol_bytes, max_size=300).map(bytes)


@st.composite
def valid_instruction(draw: st.DrawFn) -> bytes:
    """A well-formed instruction packet to one of our IDs, to broadcast or to a stranger."""
    dxl_id = draw(st.sampled_from([*IDS, 0xFE, 7]))
    kind = draw(st.sampled_from(["ping", "read", "write", "sync_read", "sync_write", "other"]))
    if kind == "ping":
        return build_instruction_packet(dxl_id, Instruction.PING)
    if kind == "read":
        address = draw(st.integers(0, 900))
        length = draw(st.integers(0, 40))
        return build_instruction_packet(
            dxl_id, Instruction.READ, address.to_bytes(2, "little") + length.to_bytes(2, "little")
        )
    if kind == "write":
        address = draw(st.sampled_from([LED_RED, 564, 565, 596, 7, 8, 562, 891]))
        data = draw(st.binary(min_size=1, max_size=4))
        return build_instruction_packet(
            dxl_id, Instruction.WRITE, address.to_bytes(2, "little") + data
        )
    if kind == "sync_read":
        listed = draw(st.lists(st.sampled_from([*IDS, 7]), max_size=3))
        return build_instruction_packet(
            0xFE, Instruction.SYNC_READ, bytes((0x63, 0x02, 4, 0, *listed))
        )
    if kind == "sync_write":
        entries = b"".join(bytes((i, draw(st.integers(0, 255)))) for i in IDS)
        return build_instruction_packet(
            0xFE, Instruction.SYNC_WRITE, bytes((0x33, 0x02, 1, 0)) + entries
        )
    instruction = draw(
        st.sampled_from([0x04, 0x05, 0x06, 0x10, 0x20, 0x8A, 0x92, 0x93, 0x9A, 0x77])
    )
    params = draw(st.binary(max_size=12))
    return build_instruction_packet(dxl_id, instruction, params)


@st.composite
def corrupted(draw: st.DrawFn, packet: bytes) -> bytes:
    """`packet` with one of: a flipped byte, an inserted byte, a deleted byte, truncation."""
    data = bytearray(packet)
    how = draw(st.sampled_from(["flip", "insert", "delete", "truncate"]))
    index = draw(st.integers(0, len(data) - 1))
    if how == "flip":
        data[index] ^= draw(st.integers(1, 255))
    elif how == "insert":
        data.insert(index, draw(st.integers(0, 255)))
    elif how == "delete":
        del data[index]
    else:
        del data[index:]
    return bytes(data)


@st.composite
def hostile_stream(draw: st.DrawFn) -> bytes:
    """Garbage, valid and corrupted packets, concatenated."""
    parts = []
    for _ in range(draw(st.integers(1, 6))):
        choice = draw(st.sampled_from(["garbage", "valid", "corrupted"]))
        if choice == "garbage":
            parts.append(draw(garbage))
        elif choice == "valid":
            parts.append(draw(valid_instruction()))
        else:
            parts.append(draw(corrupted(draw(valid_instruction()))))
    return b"".join(parts)


@st.composite
def split(draw: st.DrawFn, data: bytes) -> list[bytes]:
    """`data` cut at arbitrary points (every byte is kept, in order)."""
    if not data:
        return []
    cuts = sorted(draw(st.sets(st.integers(1, max(1, len(data) - 1)), max_size=12)))
    bounds = [0, *[c for c in cuts if c < len(data)], len(data)]
    return [data[a:b] for a, b in zip(bounds, bounds[1:], strict=False) if b > a]


# --- helpers ---------------------------------------------------------------------------------


def feed_all(parser: PacketParser, chunks: list[bytes], gaps_s: list[float]) -> list[ParsedPacket]:
    """Feed chunks at increasing times; an idle check runs at each gap (as the line does)."""
    now_s = 0.0
    found: list[ParsedPacket] = []
    for chunk, gap_s in zip(chunks, gaps_s, strict=True):
        found += parser.feed(chunk, now_s)
        now_s += gap_s
        found += parser.on_idle(now_s)
        assert parser.buffered_bytes <= MAX_PACKET_BYTES + len(chunk)
    return found


def frames_in(data: bytes, packet: ParsedPacket) -> bool:
    """True if some substring of `data` frames exactly `packet`, checked independently of the
    parser under test: CRC and unstuffing by dynamixel-sdk's own implementation."""
    start = data.find(HEADER)
    while start >= 0:
        frame = list(data[start : start + packet.wire_bytes])
        if (
            len(frame) == packet.wire_bytes >= 10
            and frame[4] == packet.packet_id
            and frame[5] | (frame[6] << 8) == packet.wire_bytes - 7
            and SDK.updateCRC(0, frame, len(frame) - 2) == frame[-2] | (frame[-1] << 8)
        ):
            unstuffed = SDK.removeStuffing(frame)
            length = unstuffed[5] | (unstuffed[6] << 8)
            region = bytes(unstuffed[7 : 7 + length - 2])
            if region == bytes((packet.instruction,)) + packet.params:
                return True
        start = data.find(HEADER, start + 1)
    return False


def make_chain() -> DynamixelChain:
    return DynamixelChain([H54Device(dxl_id, reboot_time_s=0.0) for dxl_id in IDS])


def tables(chain: DynamixelChain) -> list[bytes]:
    snapshots = []
    for device in chain.devices:
        error, data = device.read(0, TABLE_SIZE_BYTES)
        assert error == ErrorCode.NONE
        snapshots.append(data)
    return snapshots


# --- the parser ------------------------------------------------------------------------------


@examples(60)
@given(data=st.data(), stream=hostile_stream())
def test_parser_never_raises_never_invents_and_stays_bounded(
    data: st.DataObject, stream: bytes
) -> None:
    chunks = data.draw(split(stream))
    gaps = data.draw(
        st.lists(
            st.sampled_from([0.0, 0.2e-3, 1.4e-3, 1.6e-3, 0.1]),
            min_size=len(chunks),
            max_size=len(chunks),
        )
    )
    parser = PacketParser()
    found = feed_all(parser, chunks, gaps)
    found += parser.on_idle(1e6)  # the line goes quiet for good
    assert parser.buffered_bytes == 0
    for packet in found:
        if packet.crc_ok:
            assert frames_in(stream, packet), packet
    assert parser.stats.packets == sum(packet.crc_ok for packet in found)


@examples(100)
@given(data=st.data(), stream=hostile_stream())
def test_how_the_bytes_are_split_does_not_change_what_is_parsed(
    data: st.DataObject, stream: bytes
) -> None:
    whole = PacketParser().feed(stream, 0.0)
    chunks = data.draw(split(stream))
    parser = PacketParser()
    pieces = feed_all(parser, chunks, [0.0] * len(chunks))  # no idle gap: one burst
    assert pieces == whole


@examples(100)
@given(data=st.data(), junk=hostile_stream(), packet=valid_instruction())
def test_a_valid_packet_after_garbage_and_an_idle_line_is_parsed_exactly(
    data: st.DataObject, junk: bytes, packet: bytes
) -> None:
    parser = PacketParser()
    chunks = data.draw(split(junk))
    feed_all(parser, chunks, [0.5e-3] * len(chunks))
    parser.on_idle(1.0)  # > 1.5 ms after the last byte
    assert parser.buffered_bytes == 0
    assert parser.feed(packet, 2.0) == [parse_packet(packet)]
    # No pause at all: a false header in the garbage may hold the packet back until the line
    # goes idle, but the hunt resumes one byte after each false header and finds it.
    burst = PacketParser()
    found = burst.feed(junk + packet, 0.0) + burst.on_idle(1.0)
    assert parse_packet(packet) in found


# --- the chain above the parser --------------------------------------------------------------


@examples(80)
@given(data=st.data(), stream=hostile_stream(), led=st.integers(0, 255))
def test_garbage_never_corrupts_a_control_table_and_is_followed_by_exact_answers(
    data: st.DataObject, stream: bytes, led: int
) -> None:
    chain, twin = make_chain(), make_chain()
    parser = PacketParser()
    chunks = data.draw(split(stream))
    found = feed_all(parser, chunks, [0.5e-3] * len(chunks))
    found += parser.on_idle(1.0)
    for packet in found:
        chain.handle(packet, 1.0)  # replies are not checked here: only that nothing breaks
        if packet.crc_ok:
            assert frames_in(stream, packet)
            twin.handle(packet, 1.0)
    assert tables(chain) == tables(twin)
    # The devices still answer exactly (a REBOOT in the stream is over: reboot_time_s = 0).
    chain.faults.clear()
    for device in chain.devices:
        if device.item("Status Return Level") != 2 or device.item("ID") not in IDS:
            return  # a valid WRITE in the stream changed how it answers: nothing left to check
    if len({device.item("ID") for device in chain.devices}) < len(chain.devices):
        return  # a valid WRITE gave two devices one ID: both answer it, as on a real chain
    write = build_instruction_packet(
        1, Instruction.WRITE, LED_RED.to_bytes(2, "little") + bytes((led,))
    )
    read = build_instruction_packet(
        1, Instruction.READ, LED_RED.to_bytes(2, "little") + b"\x01\x00"
    )
    replies = []
    for packet in parser.feed(write + read, 2.0):
        replies += [reply for _, reply in chain.handle(packet, 2.0)]
    decoded = [parse_packet(reply) for reply in replies]
    alert = 0x80 if chain.device(1).hardware_error_status else 0
    assert [(p.packet_id, p.params) for p in decoded] == [
        (1, bytes((alert,))),
        (1, bytes((alert, led))),
    ]


# --- the line on a pty -----------------------------------------------------------------------


class FakeClock:
    def __init__(self) -> None:
        self.now_s = 10.0

    def __call__(self) -> float:
        return self.now_s


def _drain(fd: int) -> bytes:
    data = b""
    while select.select([fd], [], [], 0.0)[0]:
        try:
            chunk = os.read(fd, 4096)
        except BlockingIOError:
            break
        if not chunk:
            break
        data += chunk
    return data


def test_the_line_on_a_pty_answers_exactly_after_any_garbage() -> None:
    clock = FakeClock()
    line = DynamixelLine(make_chain(), clock=clock)
    host = os.open(line.port_path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    tty.setraw(host)
    ping = build_instruction_packet(2, Instruction.PING)
    try:

        @examples(120)
        @given(data=st.data(), stream=hostile_stream())
        def check(data: st.DataObject, stream: bytes) -> None:
            for chunk in data.draw(split(stream)):
                os.write(host, chunk)
                assert select.select([line.fileno()], [], [], 1.0)[0]
                line.on_readable()
                clock.now_s += 0.5e-3
            clock.now_s += IDLE_S
            line.on_idle()
            _drain(host)  # whatever the garbage provoked
            for device in line.chain.devices:  # a valid packet in the stream may have moved it
                device.set_item("ID", IDS[line.chain.devices.index(device)])
                device.set_item("Status Return Level", 2)
                device.set_item("Baud Rate", 1)
            line.chain.faults.clear()
            os.write(host, ping)
            assert select.select([line.fileno()], [], [], 1.0)[0]
            line.on_readable()
            assert select.select([host], [], [], 1.0)[0]
            replies = PacketParser().feed(_drain(host), 0.0)
            assert [(p.packet_id, p.crc_ok, p.params[1:]) for p in replies] == [
                (2, True, bytes((0x08, 0xD3, 1)))
            ]

        check()
    finally:
        os.close(host)
        line.close()
