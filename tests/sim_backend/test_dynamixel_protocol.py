"""Protocol 2.0 framing of the emulator: CRC, byte stuffing, packet building, streaming parser.

References: the e-Manual's example packets (Protocol 2.0, Instruction Details), the catalogue
check value of CRC-16/UMTS, and dynamixel-sdk's own packet code (an independent implementation)
driven through a fake port.
"""

from __future__ import annotations

import random

import pytest
from dynamixel_sdk import COMM_SUCCESS, PacketHandler

from sim_backend.dynamixel.protocol import (
    BYTE_TIMEOUT_S,
    MAX_PACKET_BYTES,
    Instruction,
    PacketParser,
    add_stuffing,
    build_instruction_packet,
    build_status_packet,
    crc16,
    parse_packet,
    remove_stuffing,
    wire_time_s,
)

pytestmark = pytest.mark.timeout(60)

# e-Manual Protocol 2.0 example packets, CRC bytes included (low byte first).
EMANUAL_PACKETS = [
    "FF FF FD 00 01 03 00 01 19 4E",  # ping ID 1
    "FF FF FD 00 01 07 00 55 00 06 04 26 65 5D",  # ping status ID 1
    "FF FF FD 00 FE 03 00 01 31 42",  # broadcast ping
    "FF FF FD 00 02 07 00 55 00 06 04 26 6F 6D",  # ping status ID 2
    "FF FF FD 00 01 07 00 02 84 00 04 00 1D 15",  # read
    "FF FF FD 00 01 08 00 55 00 A6 00 00 00 8C C0",  # read status
    "FF FF FD 00 01 09 00 03 74 00 00 02 00 00 CA 89",  # write
    "FF FF FD 00 01 04 00 55 00 A1 0C",  # write status
    "FF FF FD 00 01 09 00 04 68 00 C8 00 00 00 AE 8E",  # reg write
    "FF FF FD 00 01 03 00 05 02 CE",  # action
    "FF FF FD 00 01 04 00 06 01 A1 E6",  # factory reset 0x01
    "FF FF FD 00 01 03 00 08 2F 4E",  # reboot
    "FF FF FD 00 01 08 00 10 01 44 58 4C 22 B1 DC",  # clear
    "FF FF FD 00 FE 09 00 82 84 00 04 00 01 02 CE FA",  # sync read
    "FF FF FD 00 02 08 00 55 00 1F 08 00 00 BA BE",  # sync read status ID 2
    "FF FF FD 00 FE 11 00 83 74 00 04 00 01 96 00 00 00 02 AA 00 00 00 82 87",  # sync write
    "FF FF FD 00 FE 0D 00 92 01 90 00 02 00 02 92 00 01 00 1A 05",  # bulk read
    "FF FF FD 00 01 06 00 55 00 77 00 C3 69",  # bulk read status ID 1
    "FF FF FD 00 02 05 00 55 00 24 8B A9",  # bulk read status ID 2
]


class FakePort:
    """Just enough of dynamixel_sdk.PortHandler for its packet code to write/read bytes."""

    def __init__(self, incoming: bytes = b"") -> None:
        self.is_using = False
        self.written = b""
        self.incoming = bytearray(incoming)

    def clearPort(self) -> None:
        pass

    def writePort(self, packet: list[int]) -> int:
        self.written += bytes(packet)
        return len(packet)

    def readPort(self, length: int) -> list[int]:
        chunk = bytes(self.incoming[:length])
        del self.incoming[:length]
        return list(chunk)

    def isPacketTimeout(self) -> bool:
        return True


def test_crc_check_value_is_crc16_umts() -> None:
    assert crc16(b"123456789") == 0xFEE8  # catalogue check value of CRC-16/UMTS (BUYPASS)
    assert crc16(b"123456789") != 0xBB3D  # not the reflected CRC-16/ARC


@pytest.mark.parametrize("packet_hex", EMANUAL_PACKETS)
def test_crc_matches_emanual_example(packet_hex: str) -> None:
    packet = bytes.fromhex(packet_hex)
    assert crc16(packet[:-2]) == int.from_bytes(packet[-2:], "little")


def test_crc_matches_sdk_table_on_random_buffers() -> None:
    sdk = PacketHandler(2.0)
    rng = random.Random(1)
    for _ in range(500):
        data = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 80)))
        assert crc16(data) == sdk.updateCRC(0, list(data), len(data))
    assert crc16(b"world", crc16(b"hello ")) == crc16(b"hello world")


@pytest.mark.parametrize("packet_hex", EMANUAL_PACKETS)
def test_build_reproduces_emanual_packets(packet_hex: str) -> None:
    packet = bytes.fromhex(packet_hex)
    packet_id, instruction = packet[4], packet[7]
    if instruction == Instruction.STATUS:
        assert build_status_packet(packet_id, packet[8], packet[9:-2]) == packet
    else:
        assert build_instruction_packet(packet_id, instruction, packet[8:-2]) == packet


def test_stuffing_examples() -> None:
    assert add_stuffing(b"\x03\xff\xff\xfd\x00") == b"\x03\xff\xff\xfd\xfd\x00"
    assert add_stuffing(b"\xff\xff\xfd\xff\xff\xfd") == b"\xff\xff\xfd\xfd\xff\xff\xfd\xfd"
    assert add_stuffing(b"\xff\xfd\xfd\xff") == b"\xff\xfd\xfd\xff"  # no FF FF FD: unchanged
    assert remove_stuffing(b"\x03\xff\xff\xfd\xfd\x00") == b"\x03\xff\xff\xfd\x00"
    # FF FF FD FD FD: only the first FD after the pattern is stuffing
    assert remove_stuffing(b"\xff\xff\xfd\xfd\xfd") == b"\xff\xff\xfd\xfd"


def test_stuffing_round_trip_on_adversarial_data() -> None:
    rng = random.Random(2)
    alphabet = [0xFF, 0xFF, 0xFD, 0xFD, 0x00, 0x01]
    for _ in range(2000):
        region = bytes(rng.choice(alphabet) for _ in range(rng.randrange(1, 40)))
        stuffed = add_stuffing(region)
        for index in range(len(stuffed) - 2):  # every FF FF FD is followed by the stuffed FD
            if stuffed[index : index + 3] == b"\xff\xff\xfd":
                assert stuffed[index + 3 : index + 4] == b"\xfd"
        assert remove_stuffing(stuffed) == region


def test_instruction_packets_equal_what_the_sdk_sends() -> None:
    """Without anything to stuff, our builder and the SDK's txPacket agree byte for byte."""
    sdk = PacketHandler(2.0)
    port = FakePort()
    sdk.write4ByteTxOnly(port, 1, 596, -250_961)
    params = (596).to_bytes(2, "little") + (-250_961).to_bytes(4, "little", signed=True)
    assert port.written == build_instruction_packet(1, Instruction.WRITE, params)
    port = FakePort()
    sdk.syncWriteTxOnly(port, 611, 4, [1, 9, 8, 7, 6, 2, 1, 2, 3, 4], 10)
    sync_params = bytes((0x63, 0x02, 4, 0, 1, 9, 8, 7, 6, 2, 1, 2, 3, 4))
    assert port.written == build_instruction_packet(0xFE, Instruction.SYNC_WRITE, sync_params)


def test_sdk_sends_unstuffed_packets_and_the_device_side_still_reads_them() -> None:
    """dynamixel-sdk 4.1.0's addStuffing rebinds its local list when it stuffs, so txPacket
    sends the packet unstuffed (LEN and CRC of the unstuffed bytes). A device following the
    e-Manual reception rules (find header, read LEN bytes, check CRC, remove FF FF FD FD) still
    reads data containing FF FF FD 00 correctly; only FF FF FD FD in the data would lose a byte,
    on the real device as here."""
    sdk = PacketHandler(2.0)
    value = 0x00FDFFFF  # little-endian FF FF FD 00
    params = (596).to_bytes(2, "little") + value.to_bytes(4, "little")
    port = FakePort()
    sdk.write4ByteTxOnly(port, 1, 596, value)
    assert port.written != build_instruction_packet(1, Instruction.WRITE, params)  # stuffed
    assert port.written[5] == 9  # LEN of the unstuffed packet
    assert b"\xff\xff\xfd\xfd" in build_instruction_packet(1, Instruction.WRITE, params)
    for frame in (port.written, build_instruction_packet(1, Instruction.WRITE, params)):
        packet = parse_packet(frame)
        assert packet.crc_ok and packet.params == params


def test_sdk_parses_our_stuffed_status_packet() -> None:
    sdk = PacketHandler(2.0)
    data = bytes((0xFF, 0xFF, 0xFD, 0x00))
    port = FakePort(build_status_packet(3, 0x80, data))
    rxpacket, result = sdk.rxPacket(port, False)
    assert result == COMM_SUCCESS
    assert rxpacket[4] == 3 and rxpacket[8] == 0x80
    assert bytes(rxpacket[9:13]) == data


def test_parse_packet_unstuffs_params() -> None:
    params = b"\x54\x02\xff\xff\xfd\x00"
    packet = parse_packet(build_instruction_packet(7, Instruction.WRITE, params))
    assert (packet.packet_id, packet.instruction, packet.params, packet.crc_ok) == (
        7,
        Instruction.WRITE,
        params,
        True,
    )
    with pytest.raises(ValueError, match="exactly one complete"):
        parse_packet(build_instruction_packet(1, Instruction.PING)[:-1])


def test_parser_byte_by_byte_and_back_to_back() -> None:
    ping = build_instruction_packet(1, Instruction.PING)
    read = build_instruction_packet(2, Instruction.READ, b"\x63\x02\x04\x00")
    parser = PacketParser()
    found = []
    for byte in ping + read:
        found += parser.feed(bytes((byte,)), 0.0)
    assert [(p.packet_id, p.instruction) for p in found] == [(1, 1), (2, 2)]
    assert parser.buffered_bytes == 0
    assert len(parser.feed(ping + read + ping, 0.0)) == 3


def test_parser_skips_garbage_and_stuffed_pseudo_headers() -> None:
    ping = build_instruction_packet(1, Instruction.PING)
    garbage = b"\x00\xff\xff\xfd\xfd\x12\xff\xff\xff\xfd\x01\x02"  # FF FF FD FD / bad reserved
    found = PacketParser().feed(garbage + ping + b"\xff\xff" + ping, 0.0)
    assert [p.packet_id for p in found] == [1, 1]


def test_parser_reports_bad_crc_and_recovers() -> None:
    write = bytearray(build_instruction_packet(1, Instruction.WRITE, b"\x32\x02\x01"))
    write[-1] ^= 0xFF
    ping = build_instruction_packet(2, Instruction.PING)
    parser = PacketParser()
    found = parser.feed(bytes(write) + ping, 0.0)
    assert [(p.packet_id, p.crc_ok) for p in found] == [(1, False), (2, True)]
    assert found[0].instruction == Instruction.WRITE and found[0].params == b""
    assert parser.stats.crc_errors == 1


def test_oversize_length_resynchronises_at_once() -> None:
    fake = b"\xff\xff\xfd\x00\x05" + (MAX_PACKET_BYTES).to_bytes(2, "little")
    ping = build_instruction_packet(1, Instruction.PING)
    parser = PacketParser()
    assert [p.packet_id for p in parser.feed(fake + ping, 0.0)] == [1]
    assert parser.stats.oversize == 1


def test_false_header_swallowing_a_packet_is_undone_by_the_byte_timeout() -> None:
    """A false header with a long LEN would eat the next real packet; once the line is idle
    for 1.5 ms the partial frame is dropped and the real packet behind it is found."""
    fake = b"\xff\xff\xfd\x00\x05\x40\x00"  # LEN 64: waits for 64 more bytes
    ping = build_instruction_packet(1, Instruction.PING)
    parser = PacketParser()
    assert parser.feed(fake + ping, 10.0) == []
    assert parser.idle_deadline_s == pytest.approx(10.0 + BYTE_TIMEOUT_S)
    assert parser.on_idle(10.0 + 0.5 * BYTE_TIMEOUT_S) == []  # not idle long enough
    found = parser.on_idle(10.0 + BYTE_TIMEOUT_S)
    assert [p.packet_id for p in found] == [1]
    assert parser.stats.byte_timeouts >= 1 and parser.buffered_bytes == 0


def test_truncated_packet_is_dropped_only_after_idle() -> None:
    read = build_instruction_packet(1, Instruction.READ, b"\x63\x02\x04\x00")
    parser = PacketParser()
    assert parser.feed(read[:8], 0.0) == []
    # the rest arrives 1 ms later: still one packet
    assert [p.instruction for p in parser.feed(read[8:], 1e-3)] == [Instruction.READ]
    assert parser.feed(read[:8], 2.0) == []
    assert parser.on_idle(2.0 + 2e-3) == []  # dropped
    assert parser.buffered_bytes == 0
    ping = build_instruction_packet(1, Instruction.PING)
    assert [p.instruction for p in parser.feed(ping, 3.0)] == [Instruction.PING]


def test_parser_survives_seeded_garbage_and_finds_every_valid_packet() -> None:
    rng = random.Random(3)
    alphabet = [0xFF, 0xFF, 0xFF, 0xFD, 0xFD, 0x00, 0x00, 0x01, 0x03, 0x07, 0xFE]
    parser = PacketParser()
    expected = []
    found = []
    now_s = 0.0
    for k in range(300):
        garbage = bytes(
            rng.choice(alphabet) if rng.random() < 0.7 else rng.randrange(256)
            for _ in range(rng.randrange(0, 60))
        )
        packet_id = 1 + k % 5
        packet = build_instruction_packet(packet_id, Instruction.READ, bytes((k & 0xFF, 2, 4, 0)))
        expected.append((packet_id, bytes((k & 0xFF, 2, 4, 0))))
        found += parser.feed(garbage, now_s)
        found += parser.feed(packet, now_s)
        assert parser.buffered_bytes <= MAX_PACKET_BYTES
        now_s += 0.01  # the host waits for a reply: the line goes idle between packets
        found += parser.on_idle(now_s)
    valid = [(p.packet_id, p.params) for p in found if p.crc_ok and p.instruction == 2]
    # every valid packet found, in order (garbage could in theory add more; it did not)
    assert valid == expected


def test_wire_time() -> None:
    assert wire_time_s(10, 1_000_000) == pytest.approx(1e-4)
    assert wire_time_s(14, 57_600) == pytest.approx(14 * 10 / 57_600)


def test_status_packets_from_the_cached_header_equal_the_frame_byte_for_byte() -> None:
    """`build_status_packet` (the header's CRC cached per ID and length, the CRC continued over
    the error and params; stuffed packets the long way) against the frame written out: header,
    ID, LEN of the stuffed region, the stuffed region 0x55 error params, the SDK's CRC."""
    sdk = PacketHandler(2.0)
    rng = random.Random(7)
    stuffed = 0
    for _ in range(3000):
        packet_id = rng.randrange(0, 253)
        error = rng.randrange(256)
        alphabet = [0xFF, 0xFD, 0x00, rng.randrange(256)]  # FF FF FD runs are frequent
        params = bytes(rng.choice(alphabet) for _ in range(rng.randrange(0, 40)))
        region = add_stuffing(bytes((0x55, error)) + params)
        stuffed += len(region) > len(params) + 2
        head = bytes((0xFF, 0xFF, 0xFD, 0x00, packet_id, (len(region) + 2) & 0xFF))
        frame = head + bytes(((len(region) + 2) >> 8,)) + region
        crc = sdk.updateCRC(0, list(frame), len(frame))
        expected = frame + bytes((crc & 0xFF, crc >> 8))
        assert build_status_packet(packet_id, error, params) == expected
    assert stuffed > 50  # the stuffed path ran too
