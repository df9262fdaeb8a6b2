"""Dynamixel Protocol 2.0 framing, device side: CRC, byte stuffing, packets, a streaming parser.

Frame (ROBOTIS e-Manual, "Protocol 2.0", Instruction/Status Packet)::

    FF FF FD 00 | ID | LEN_L LEN_H | INST | params... | CRC_L CRC_H

LEN counts INST + params + the two CRC bytes. A status packet has INST 0x55 and an error byte
before its params (the error byte counts as a param). Multi-byte values are little-endian.

Byte stuffing (e-Manual "Packet Process"): over the region from the instruction byte to the last
param, every ``FF FF FD`` becomes ``FF FF FD FD``; LEN is then recomputed and the CRC is
computed over the stuffed packet. A receiver checks the CRC on the stuffed bytes, then unstuffs.

Measured: dynamixel-sdk 4.1.0 transmits instruction packets unstuffed (its addStuffing rebinds a
local list when it stuffs, and txPacket discards the result). A device following the reception
rules above (find the header, take LEN bytes, check the CRC, remove ``FF FF FD FD``) still reads
data containing ``FF FF FD 00`` correctly, and so does `PacketParser`; data containing
``FF FF FD FD`` loses a byte, on the real device as here.

CRC (e-Manual "CRC Calculation"): CRC-16 with generator 0x8005, initial value 0, not reflected,
no final XOR (catalogue name CRC-16/UMTS or BUYPASS; check value of "123456789" is 0xFEE8). It is
not the reflected CRC-16/ARC.
"""

from __future__ import annotations

import enum
import struct
from dataclasses import dataclass, field

import numpy as np

HEADER = b"\xff\xff\xfd"
RESERVED = 0x00
BROADCAST_ID = 0xFE
MAX_DEVICE_ID = 252  # 0xFD and 0xFF are never IDs: they would clash with the header
STATUS_INSTRUCTION = 0x55
ALERT_BIT = 0x80

# Fixed bytes of a packet around its params: header(3) + reserved + ID + LEN(2) + INST + CRC(2).
INSTRUCTION_OVERHEAD_BYTES = 10
STATUS_OVERHEAD_BYTES = 11  # plus the error byte

BITS_PER_BYTE_ON_WIRE = 10  # 8N1: start bit + 8 data bits + stop bit

# The Python SDK never sends more than 1024 bytes (TXPACKET_MAX_LEN in dynamixel_sdk); a device
# that sees a larger LEN field is looking at garbage, so the parser resynchronises.
MAX_PACKET_BYTES = 1024

# e-Manual "Protocol 2.0": a device drops an instruction whose bytes stop for more than 1.5 ms.
BYTE_TIMEOUT_S = 1.5e-3


class Instruction(enum.IntEnum):
    """Instruction codes (e-Manual "Protocol 2.0", Instruction; dynamixel_sdk robotis_def.py)."""

    PING = 0x01
    READ = 0x02
    WRITE = 0x03
    REG_WRITE = 0x04
    ACTION = 0x05
    FACTORY_RESET = 0x06
    REBOOT = 0x08
    CLEAR = 0x10
    CONTROL_TABLE_BACKUP = 0x20
    STATUS = 0x55
    SYNC_READ = 0x82
    SYNC_WRITE = 0x83
    FAST_SYNC_READ = 0x8A
    BULK_READ = 0x92
    BULK_WRITE = 0x93
    FAST_BULK_READ = 0x9A


class ErrorCode(enum.IntEnum):
    """Error numbers of the status packet's error byte, bits 6..0 (e-Manual "Status Packet")."""

    NONE = 0
    RESULT_FAIL = 1
    INSTRUCTION = 2
    CRC = 3
    DATA_RANGE = 4
    DATA_LENGTH = 5
    DATA_LIMIT = 6
    ACCESS = 7


def _make_crc_table(polynomial: int) -> tuple[int, ...]:
    """The 256-entry MSB-first lookup table of a 16-bit CRC with the given generator."""
    table = []
    for byte in range(256):
        crc = byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ polynomial) if crc & 0x8000 else (crc << 1)
        table.append(crc & 0xFFFF)
    return tuple(table)


_CRC_TABLE = _make_crc_table(0x8005)


def _make_crc_word_table(byte_table: tuple[int, ...]) -> list[int]:
    """The 65536-entry table that advances the CRC by two bytes at once: after 16 bits the old
    register has shifted out entirely, so crc' = T16[crc ^ (b0 << 8 | b1)], T16[v] being the
    CRC of the two bytes of v from 0 (the byte table applied twice)."""
    table = np.array(byte_table, dtype=np.uint32)
    word = np.arange(1 << 16, dtype=np.uint32)
    first = table[word >> 8]
    return (((first << 8) & 0xFFFF) ^ table[((first >> 8) ^ (word & 0xFF)) & 0xFF]).tolist()


_CRC_WORD_TABLE = _make_crc_word_table(_CRC_TABLE)
_WORD_UNPACKERS: dict[int, struct.Struct] = {}  # big-endian 16-bit words, by count


def crc16(data: bytes | bytearray | memoryview, crc: int = 0) -> int:
    """CRC-16 of Protocol 2.0 (poly 0x8005, init 0, not reflected, no XOR out).

    `crc` continues a running CRC, so crc16(b, crc16(a)) == crc16(a + b). Two bytes per step
    (`_CRC_WORD_TABLE`), the last odd byte with the byte table as dynamixel-sdk does."""
    length = len(data)
    words = _WORD_UNPACKERS.get(length >> 1)
    if words is None:
        words = _WORD_UNPACKERS.setdefault(length >> 1, struct.Struct(f">{length >> 1}H"))
    table = _CRC_WORD_TABLE
    for word in words.unpack_from(data):
        crc = table[crc ^ word]
    if length & 1:
        crc = ((crc << 8) & 0xFFFF) ^ _CRC_TABLE[((crc >> 8) ^ data[-1]) & 0xFF]
    return crc


def add_stuffing(region: bytes | bytearray) -> bytes:
    """Stuff the instruction..last-param region: each ``FF FF FD`` becomes ``FF FF FD FD``."""
    if HEADER not in region:
        return bytes(region)
    out = bytearray()
    for byte in region:
        out.append(byte)
        if byte == 0xFD and len(out) >= 3 and out[-3] == 0xFF and out[-2] == 0xFF:
            out.append(0xFD)
    return bytes(out)


def remove_stuffing(region: bytes | bytearray) -> bytes:
    """Undo `add_stuffing`: drop the extra ``FD`` after each ``FF FF FD`` of the region."""
    if HEADER + b"\xfd" not in region:
        return bytes(region)
    out = bytearray()
    index = 0
    length = len(region)
    while index < length:
        byte = region[index]
        out.append(byte)
        index += 1
        if (
            byte == 0xFD
            and index < length
            and region[index] == 0xFD
            and len(out) >= 3
            and out[-3] == 0xFF
            and out[-2] == 0xFF
        ):
            index += 1  # skip the stuffed FD
    return bytes(out)


def _frame(packet_id: int, unstuffed_region: bytes) -> bytes:
    """Header + ID + LEN + stuffed region + CRC over all of it."""
    if not 0 <= packet_id <= 0xFF:
        raise ValueError(f"packet ID must be 0..255, got {packet_id}")
    region = add_stuffing(unstuffed_region)
    length = len(region) + 2
    packet = bytearray(HEADER)
    packet += bytes((RESERVED, packet_id, length & 0xFF, length >> 8))
    packet += region
    crc = crc16(packet)
    packet += bytes((crc & 0xFF, crc >> 8))
    return bytes(packet)


def build_instruction_packet(packet_id: int, instruction: int, params: bytes = b"") -> bytes:
    """An instruction packet as the host sends it (stuffed, with CRC)."""
    if not 0 <= instruction <= 0xFF:
        raise ValueError(f"instruction must be one byte, got {instruction}")
    return _frame(packet_id, bytes((instruction,)) + bytes(params))


# (ID, LEN) -> the status packet's first 8 bytes (header .. INST) and their CRC
_STATUS_PREFIXES: dict[tuple[int, int], tuple[bytes, int]] = {}


def build_status_packet(packet_id: int, error: int, params: bytes = b"") -> bytes:
    """A status packet as a device sends it: INST 0x55, error byte, params (stuffed, with CRC).

    The usual packet needs no stuffing (no FF FF FD in error + params: the region's first byte,
    0x55, cannot start one): its first 8 bytes and their CRC are those of every packet of this
    ID and length, computed once; the CRC goes on over the rest."""
    if not 0 <= error <= 0xFF:
        raise ValueError(f"status error must be one byte, got {error}")
    body = bytes((error,)) + bytes(params)
    if HEADER in body:
        return _frame(packet_id, bytes((STATUS_INSTRUCTION,)) + body)
    key = (packet_id, len(body) + 3)
    prefix = _STATUS_PREFIXES.get(key)
    if prefix is None:
        head = _frame(packet_id, bytes((STATUS_INSTRUCTION,)))[:-2]
        head = head[:5] + bytes((key[1] & 0xFF, key[1] >> 8)) + head[7:]
        prefix = _STATUS_PREFIXES.setdefault(key, (head, crc16(head)))
    crc = crc16(body, prefix[1])
    return prefix[0] + body + bytes((crc & 0xFF, crc >> 8))


def wire_time_s(n_bytes: int, baud_bps: int) -> float:
    """Time `n_bytes` occupy an 8N1 line at `baud_bps` (10 bits per byte)."""
    return n_bytes * BITS_PER_BYTE_ON_WIRE / baud_bps


@dataclass(frozen=True)
class ParsedPacket:
    """One framed packet found on the line.

    `params` are unstuffed. `crc_ok` False means the frame was complete but its CRC did not match:
    then only `packet_id` and the (untrusted) `instruction` byte are meaningful and `params` is
    empty. `wire_bytes` is the frame's length as it was on the wire (stuffed), for timing.
    """

    packet_id: int
    instruction: int
    params: bytes
    crc_ok: bool
    wire_bytes: int


def parse_packet(frame: bytes | bytearray) -> ParsedPacket:
    """Parse exactly one complete frame (for tests and tools); ValueError if it is not one."""
    parser = PacketParser()
    packets = parser.feed(frame, 0.0)
    if len(packets) != 1 or parser.buffered_bytes:
        raise ValueError(
            f"expected exactly one complete Protocol 2.0 frame, found {len(packets)} packet(s) "
            f"and {parser.buffered_bytes} leftover byte(s) in {bytes(frame).hex(' ')}"
        )
    return packets[0]


@dataclass
class ParserStats:
    """What the parser has seen since it was made."""

    packets: int = 0
    crc_errors: int = 0
    discarded_bytes: int = 0  # bytes skipped while hunting for a header
    byte_timeouts: int = 0  # partial packets dropped after the line went idle
    oversize: int = 0  # headers with an impossible LEN


@dataclass
class PacketParser:
    """Streaming Protocol 2.0 frame finder for the device side of the line.

    Feed it whatever bytes arrive (`feed`); it returns each complete frame it finds. It never
    raises on garbage and never waits on a frame forever:

    - hunts for ``FF FF FD 00`` (a stuffed ``FF FF FD FD`` is not a header) with a valid ID
      (0..252 or broadcast) and a plausible LEN (3 .. `max_packet_bytes` - 7); anything else
      costs one byte and the hunt goes on;
    - a complete frame with a bad CRC is reported (`crc_ok=False`) and the hunt restarts one
      byte after its header, so a real packet swallowed by a false header is still found;
    - `on_idle(now_s)`: once the line has been quiet for `byte_timeout_s` (e-Manual: 1.5 ms
      between bytes) a partial frame is abandoned and the bytes after its header are searched
      again. Time is "when the bytes were read", passed in by the caller: the caller must only
      call `on_idle` after a read found the line empty, so a descheduled process never drops
      bytes that were already waiting.
    - the buffer is bounded by one maximum-size frame (plus whatever one `feed` brings).
    """

    byte_timeout_s: float = BYTE_TIMEOUT_S
    max_packet_bytes: int = MAX_PACKET_BYTES
    stats: ParserStats = field(default_factory=ParserStats)
    _buffer: bytearray = field(default_factory=bytearray, repr=False)
    _last_rx_s: float = field(default=0.0, repr=False)

    @property
    def buffered_bytes(self) -> int:
        """Bytes held back as the start of a frame not complete yet."""
        return len(self._buffer)

    @property
    def idle_deadline_s(self) -> float | None:
        """When a held-back partial frame times out, or None when nothing is held."""
        if not self._buffer:
            return None
        return self._last_rx_s + self.byte_timeout_s

    def reset(self) -> None:
        """Forget any partial frame."""
        self._buffer.clear()

    def feed(self, data: bytes | bytearray, now_s: float) -> list[ParsedPacket]:
        """Add bytes read at `now_s`; return the frames they complete, in order."""
        if not data:
            return []
        self._buffer += data
        self._last_rx_s = now_s
        return self._scan()

    def on_idle(self, now_s: float) -> list[ParsedPacket]:
        """The line was found empty at `now_s`: drop a stale partial frame and rescan after it."""
        found: list[ParsedPacket] = []
        while self._buffer and now_s - self._last_rx_s >= self.byte_timeout_s:
            self.stats.byte_timeouts += 1
            self._discard(1)
            found += self._scan()
        return found

    def _discard(self, count: int) -> None:
        del self._buffer[:count]
        self.stats.discarded_bytes += count

    def _scan(self) -> list[ParsedPacket]:
        found: list[ParsedPacket] = []
        buf = self._buffer
        max_length_field = self.max_packet_bytes - 7
        while True:
            start = buf.find(HEADER)
            if start < 0:
                # Keep a trailing FF or FF FF: it may be the start of the next header.
                keep = 2 if buf.endswith(b"\xff\xff") else 1 if buf.endswith(b"\xff") else 0
                self._discard(len(buf) - keep)
                return found
            if start:
                self._discard(start)
            if len(buf) < 7:
                return found  # header seen, ID/LEN not yet
            packet_id = buf[4]
            length = buf[5] | (buf[6] << 8)
            if buf[3] != RESERVED or not (packet_id <= MAX_DEVICE_ID or packet_id == BROADCAST_ID):
                self._discard(1)
                continue
            if length < 3 or length > max_length_field:
                self.stats.oversize += length > max_length_field
                self._discard(1)
                continue
            total = 7 + length
            if len(buf) < total:
                return found  # wait for the rest (or the byte timeout)
            received_crc = buf[total - 2] | (buf[total - 1] << 8)
            if crc16(bytes(buf[: total - 2])) != received_crc:
                self.stats.crc_errors += 1
                found.append(ParsedPacket(packet_id, buf[7], b"", False, total))
                self._discard(1)
                continue
            region = remove_stuffing(buf[7 : total - 2])
            found.append(ParsedPacket(packet_id, region[0], bytes(region[1:]), True, total))
            self.stats.packets += 1
            del buf[:total]
