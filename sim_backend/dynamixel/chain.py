"""Several PRO devices on one RS-485 line: who executes an instruction, who answers, and when.

Line semantics (ROBOTIS e-Manual "Protocol 2.0"):
- Unicast (ID 0..252): the device(s) with that ID execute; the reply obeys Status Return Level.
  An instruction a Pro does not know (CLEAR, CONTROL_TABLE_BACKUP, FAST_SYNC_READ,
  FAST_BULK_READ, anything else) gets Instruction Error (2); SYNC/BULK instructions must be
  broadcast, so unicast ones get Instruction Error too. Parameters of the wrong length get Data
  Length Error (5) (the e-Manual does not say; our choice).
- Broadcast (0xFE): PING -> every device answers, in ID order; READ -> nothing happens;
  WRITE / REG_WRITE / ACTION / REBOOT / FACTORY_RESET -> executed by every device, no reply
  (FACTORY_RESET with 0xFF is refused, e-Manual "Factory Reset"); SYNC_WRITE / BULK_WRITE ->
  executed, no reply; SYNC_READ / BULK_READ -> one status per listed ID, in listed order.
  A listed ID that does not answer (absent, silent, rebooting, Status Return Level 0) stops
  the sequence: the devices after it do not answer either, because each waits for the status
  of the one before it (ROBOTIS maintainer, DynamixelSDK issue #364). FAST_SYNC_READ and
  FAST_BULK_READ are not supported by the legacy Pro (e-Manual's list of supporting devices):
  it ignores them like any broadcast instruction it does not know, so the host times out.
- Status Return Level is consulted after the instruction ran, so a WRITE that lowers it is
  already not answered (the e-Manual does not say which; our choice).
- A WRITE that changes ID or Baud Rate is answered from the old ID (and, with `enforce_baud`,
  heard at the old speed); from then on the device answers to the new ones (our choice).
- A frame with a bad CRC addressed to one of our IDs gets CRC Error (3) from that device.
- A malformed SYNC/BULK packet (parameter count not matching its own layout) is ignored.
- With `enforce_baud`, a device whose Baud Rate differs from the line speed hears only garbage:
  it neither executes nor answers.

Timing (the wire model): each reply carries the time it must reach the host. The instruction
takes its wire time (10 bits per byte at the line baud); then each replying device waits its
Return Delay Time (9) after the end of the previous packet on the line and sends its status,
which takes its own wire time. Instant-mode lines ignore these times and write at once.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from functools import partial

from sim_backend.dynamixel.device import FACTORY_RESET_ALL, DynamixelProDevice
from sim_backend.dynamixel.faults import LineFaults
from sim_backend.dynamixel.protocol import (
    BROADCAST_ID,
    ErrorCode,
    Instruction,
    ParsedPacket,
    build_status_packet,
    parse_packet,
    wire_time_s,
)

Reply = tuple[float, bytes]  # (time the last byte reaches the host, status packet bytes)

_FALLBACK_BAUD_BPS = 1_000_000  # only for timing a packet nobody hears (then nothing replies)


class _ReplySchedule:
    """Status packets in line order, each timed after the one before it."""

    def __init__(self, start_s: float, line_baud_bps: int | None, faults: LineFaults) -> None:
        self.cursor_s = start_s
        self.line_baud_bps = line_baud_bps
        self.faults = faults
        self.replies: list[Reply] = []

    def add(
        self, device: DynamixelProDevice, reply_id: int, error: int, params: bytes = b""
    ) -> None:
        packet = build_status_packet(reply_id, device.status_error(error), params)
        baud = self.line_baud_bps or device.baud_bps
        self.cursor_s += device.return_delay_s + wire_time_s(len(packet), baud)
        faults = self.faults
        if not faults.replies_intact:
            if faults.take_drop(reply_id):
                return  # sent, but lost before the host
            if faults.take_corrupt(reply_id):
                packet = packet[:-1] + bytes((packet[-1] ^ 0xA5,))
        self.replies.append((self.cursor_s, packet))


class DynamixelChain:
    """The devices on one line plus the line's fault knobs; `handle` is one instruction."""

    def __init__(
        self,
        devices: Iterable[DynamixelProDevice],
        *,
        faults: LineFaults | None = None,
        enforce_baud: bool = False,
    ) -> None:
        self.devices: tuple[DynamixelProDevice, ...] = tuple(devices)
        ids = [device.dxl_id for device in self.devices]
        duplicates = sorted({i for i in ids if ids.count(i) > 1})
        if duplicates:
            raise ValueError(f"two devices on one line share ID(s) {duplicates}: IDs must differ")
        self.faults = faults if faults is not None else LineFaults()
        self.enforce_baud = enforce_baud
        self._tick_listeners: list[Callable[[float], None]] = []

    def device(self, dxl_id: int) -> DynamixelProDevice:
        """The device that currently has ID `dxl_id` (KeyError if none)."""
        for device in self.devices:
            if device.dxl_id == dxl_id:
                return device
        present = sorted(device.dxl_id for device in self.devices)
        raise KeyError(f"no device with ID {dxl_id} on this line (IDs present: {present})")

    def add_tick_listener(self, fn: Callable[[float], None]) -> None:
        """`fn(now_s)` runs before every instruction is executed (firmware catches up)."""
        self._tick_listeners.append(fn)

    def handle(
        self,
        packet: ParsedPacket | bytes | bytearray,
        now_s: float,
        *,
        line_baud_bps: int | None = None,
    ) -> list[Reply]:
        """Execute one instruction that finished arriving at `now_s`; return the replies.

        `packet`: a `ParsedPacket` from `PacketParser`, or the bytes of exactly one frame.
        `line_baud_bps`: the host's line speed if known (pty termios); timing falls back to
        each device's own Baud Rate when None, and `enforce_baud` needs it.
        """
        if not isinstance(packet, ParsedPacket):
            packet = parse_packet(packet)
        for listener in self._tick_listeners:
            listener(now_s)
        hearing = [d for d in self.devices if self._hears(d, now_s, line_baud_bps)]
        if self.faults.silent_ids:
            self.faults.fired.instructions_unheard += sum(
                1
                for d in self.devices
                if d.dxl_id in self.faults.silent_ids
                and packet.packet_id in (d.dxl_id, BROADCAST_ID)
                and d.available(now_s)
            )
        instruction_baud = line_baud_bps or (hearing[0].baud_bps if hearing else _FALLBACK_BAUD_BPS)
        schedule = _ReplySchedule(
            now_s + wire_time_s(packet.wire_bytes, instruction_baud), line_baud_bps, self.faults
        )
        if packet.packet_id == BROADCAST_ID:
            if packet.crc_ok:
                self._broadcast(packet, hearing, schedule, now_s)
        else:
            for device in hearing:
                if device.dxl_id == packet.packet_id:
                    self._unicast(packet, device, schedule, now_s)
        return schedule.replies

    # ---------------------------------------------------------------- internals

    def _hears(self, device: DynamixelProDevice, now_s: float, line_baud_bps: int | None) -> bool:
        if not device.available(now_s) or device.dxl_id in self.faults.silent_ids:
            return False
        if self.enforce_baud and line_baud_bps is not None:
            return device.baud_bps == line_baud_bps
        return True

    def _unicast(
        self,
        packet: ParsedPacket,
        device: DynamixelProDevice,
        schedule: _ReplySchedule,
        now_s: float,
    ) -> None:
        instruction = packet.instruction
        reply_id = packet.packet_id
        if not packet.crc_ok:
            if device.replies_to(instruction):
                schedule.add(device, reply_id, ErrorCode.CRC)
            return
        params = packet.params
        data = b""
        after: Callable[[], None] | None = None
        if instruction == Instruction.PING:
            error, data = ErrorCode.NONE, device.ping()
        elif instruction == Instruction.READ:
            if len(params) != 4:
                error = ErrorCode.DATA_LENGTH
            else:
                error, data = device.read(_u16(params, 0), _u16(params, 2))
        elif instruction in (Instruction.WRITE, Instruction.REG_WRITE):
            if len(params) < 2:
                error = ErrorCode.DATA_LENGTH
            elif instruction == Instruction.WRITE:
                error = device.write(_u16(params, 0), params[2:])
            else:
                error = device.reg_write(_u16(params, 0), params[2:])
        elif instruction == Instruction.ACTION:
            error = device.action()
        elif instruction == Instruction.REBOOT:
            error = ErrorCode.NONE
            after = partial(device.reboot, now_s)
        elif instruction == Instruction.FACTORY_RESET:
            if len(params) != 1:
                error = ErrorCode.DATA_LENGTH
            else:
                error = device.check_factory_reset(params[0])
                if error == ErrorCode.NONE:
                    after = partial(device.factory_reset, params[0], now_s)
        else:
            error = ErrorCode.INSTRUCTION
        if device.replies_to(instruction):
            schedule.add(device, reply_id, error, data)
        if after is not None:
            after()  # the status was built first: it carries the pre-reboot state

    def _broadcast(
        self,
        packet: ParsedPacket,
        hearing: list[DynamixelProDevice],
        schedule: _ReplySchedule,
        now_s: float,
    ) -> None:
        instruction = packet.instruction
        params = packet.params
        if instruction == Instruction.PING:
            for device in sorted(hearing, key=lambda d: d.dxl_id):
                schedule.add(device, device.dxl_id, ErrorCode.NONE, device.ping())
        elif instruction == Instruction.WRITE and len(params) >= 2:
            for device in hearing:
                device.write(_u16(params, 0), params[2:])
        elif instruction == Instruction.REG_WRITE and len(params) >= 2:
            for device in hearing:
                device.reg_write(_u16(params, 0), params[2:])
        elif instruction == Instruction.ACTION:
            for device in hearing:
                device.action()
        elif instruction == Instruction.REBOOT:
            for device in hearing:
                device.reboot(now_s)
        elif instruction == Instruction.FACTORY_RESET and len(params) == 1:
            if params[0] != FACTORY_RESET_ALL:  # broadcast "reset all" is refused
                for device in hearing:
                    if device.check_factory_reset(params[0]) == ErrorCode.NONE:
                        device.factory_reset(params[0], now_s)
        elif instruction == Instruction.SYNC_READ:
            self._sync_read(params, hearing, schedule)
        elif instruction == Instruction.SYNC_WRITE:
            self._sync_write(params, hearing)
        elif instruction == Instruction.BULK_READ:
            self._bulk_read(params, hearing, schedule)
        elif instruction == Instruction.BULK_WRITE:
            self._bulk_write(params, hearing)
        # READ, FAST_SYNC_READ, FAST_BULK_READ and unknown instructions: nothing happens.

    @staticmethod
    def _answering(
        by_id: dict[int, DynamixelProDevice], dxl_id: int, instruction: int
    ) -> DynamixelProDevice | None:
        device = by_id.get(dxl_id)
        if device is not None and device.replies_to(instruction):
            return device
        return None

    def _sync_read(
        self, params: bytes, hearing: list[DynamixelProDevice], schedule: _ReplySchedule
    ) -> None:
        if len(params) < 4:
            return
        address, length = _u16(params, 0), _u16(params, 2)
        by_id = {device.dxl_id: device for device in hearing}
        for dxl_id in params[4:]:
            device = self._answering(by_id, dxl_id, Instruction.SYNC_READ)
            if device is None:
                return  # the rest wait for a status that never comes
            error, data = device.read(address, length)
            schedule.add(device, dxl_id, error, data)

    def _bulk_read(
        self, params: bytes, hearing: list[DynamixelProDevice], schedule: _ReplySchedule
    ) -> None:
        if not params or len(params) % 5:
            return
        by_id = {device.dxl_id: device for device in hearing}
        for offset in range(0, len(params), 5):
            dxl_id = params[offset]
            device = self._answering(by_id, dxl_id, Instruction.BULK_READ)
            if device is None:
                return
            error, data = device.read(_u16(params, offset + 1), _u16(params, offset + 3))
            schedule.add(device, dxl_id, error, data)

    @staticmethod
    def _sync_write(params: bytes, hearing: list[DynamixelProDevice]) -> None:
        if len(params) < 4:
            return
        address, length = _u16(params, 0), _u16(params, 2)
        body = params[4:]
        if length == 0 or not body or len(body) % (1 + length):
            return
        by_id = {device.dxl_id: device for device in hearing}
        for offset in range(0, len(body), 1 + length):
            device = by_id.get(body[offset])
            if device is not None:
                device.write(address, body[offset + 1 : offset + 1 + length])

    @staticmethod
    def _bulk_write(params: bytes, hearing: list[DynamixelProDevice]) -> None:
        entries: list[tuple[int, int, bytes]] = []
        offset = 0
        while offset < len(params):
            if offset + 5 > len(params):
                return
            length = _u16(params, offset + 3)
            end = offset + 5 + length
            if length == 0 or end > len(params):
                return
            entries.append((params[offset], _u16(params, offset + 1), params[offset + 5 : end]))
            offset = end
        by_id = {device.dxl_id: device for device in hearing}
        for dxl_id, address, data in entries:
            device = by_id.get(dxl_id)
            if device is not None:
                device.write(address, data)


def _u16(data: bytes, offset: int) -> int:
    return data[offset] | (data[offset + 1] << 8)
