"""The emulated RS-485 line on a pseudo-terminal: bytes in, frames parsed, replies out on time.

`DynamixelLine` is an endpoint for a single-threaded event loop (select/poll on `fileno()`):

    while running:
        wait until fileno() is readable or next_due_s() is reached
        line.on_readable() if readable else line.on_idle()
        line.flush_due()

Pty facts this relies on (measured on Linux): a fresh pty is in cooked mode, so
the emulator puts it in raw mode itself; the master gets EIO/HUP whenever no slave fd is open,
which happens every time the SDK's setBaudRate() closes and reopens the port, so the emulator
keeps its own slave fd open for the life of the line; a pty moves bytes instantly, whatever
baud the host set, so realistic timing is modelled as reply due times (realtime mode).

Modes:
- instant (default): every reply is written as soon as its instruction is parsed.
- realtime: replies are held until the wire model's due time (see `DynamixelChain`); if the host
  starts sending again while replies are still held, those replies are discarded (on a
  half-duplex bus they would collide with the host's packet). With `adapter_latency_s`, a reply
  that left the wire waits that much more in the USB-serial adapter before the host sees it:
  the adapter (an FTDI chip) passes a short packet on only when its latency timer expires
  (16 ms by default, 1 ms when set), the cost a rehearsal should show.

The byte timeout (1.5 ms, e-Manual) drops a partial frame only when the line has really been
idle: bytes are timestamped when they are read, and `on_idle` first reads again and only times
out when that read finds nothing, so a descheduled emulator never drops bytes that were waiting.

Line speed: read from the pty's termios (set by the host, e.g. pyserial) on the slave fd we
keep. With `DynamixelChain(enforce_baud=True)` a device whose Baud Rate differs hears garbage
and stays silent; in realtime mode the same speed times the wire.
"""

from __future__ import annotations

import os
import select
import termios
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from sim_backend.dynamixel.chain import DynamixelChain, Reply
from sim_backend.dynamixel.protocol import Instruction, PacketParser, ParsedPacket
from sim_backend.pseudo_terminal import RawPty

_STANDARD_BAUDS = (
    9_600,
    19_200,
    38_400,
    57_600,
    115_200,
    230_400,
    460_800,
    500_000,
    576_000,
    921_600,
    1_000_000,
    1_152_000,
    1_500_000,
    2_000_000,
    2_500_000,
    3_000_000,
    3_500_000,
    4_000_000,
)
_TERMIOS_SPEED_TO_BPS: dict[int, int] = {
    getattr(termios, f"B{bps}"): bps for bps in _STANDARD_BAUDS if hasattr(termios, f"B{bps}")
}
_READ_CHUNK_BYTES = 4096
# Instructions that only report the device's state: held back by drain(hold_reads=True).
_READS = frozenset(
    (
        Instruction.PING,
        Instruction.READ,
        Instruction.SYNC_READ,
        Instruction.FAST_SYNC_READ,
        Instruction.BULK_READ,
    )
)


@dataclass
class LineStats:
    bytes_in: int = 0
    bytes_out: int = 0
    replies_sent: int = 0
    replies_discarded: int = 0  # held replies dropped because the host talked over them
    replies_overflowed: int = 0  # the host was not reading and the pty buffer was full


class DynamixelLine:
    """A `DynamixelChain` answering on a pty; hand `port_path` to the SDK."""

    def __init__(
        self,
        chain: DynamixelChain,
        *,
        realtime: bool = False,
        clock: Callable[[], float] = time.monotonic,
        adapter_latency_s: float = 0.0,
        hold_reads: bool = False,
    ) -> None:
        """hold_reads: read instructions (and pings) wait for `release_held_reads()`, writes
        run at once: the lock-step emulator must see a SYNC the host sent before a read, which
        may still sit unread on the CAN side when the read arrives, before it answers."""
        if adapter_latency_s < 0 or (adapter_latency_s and not realtime):
            raise ValueError("adapter_latency_s must be >= 0, and only in realtime mode")
        self.chain = chain
        self.realtime = realtime
        self.clock = clock
        self.adapter_latency_s = adapter_latency_s
        self.parser = PacketParser()
        self.stats = LineStats()
        self._pending: list[Reply] = []  # (wire due time, packet): still on the bus
        self._in_adapter: list[Reply] = []  # (delivery time, packet): off the bus, not passed on
        self.hold_reads = hold_reads
        self._held_reads: list[ParsedPacket] = []
        self._pty = RawPty()
        self.port_path: str = self._pty.path
        self._closed = False

    def fileno(self) -> int:
        """The pty master: readable when the host has written bytes."""
        return self._pty.master_fd

    @property
    def line_baud_bps(self) -> int | None:
        """The speed the host set on the port (termios), or None if it is not a standard one."""
        speed = self._pty.termios_speed()
        return _TERMIOS_SPEED_TO_BPS.get(speed)

    def on_readable(self) -> None:
        """Read what is there, parse it, execute it, write or queue the replies."""
        data = self._read_available()
        if data:
            self._process(data, self.clock())

    def on_idle(self) -> None:
        """A poll found nothing: apply the byte timeout to a partial frame (see module doc).
        (It reads first even without one: in lock-step a read that came while the plant
        stepped is answered in this turn of the loop, not after one more select.)"""
        now_s = self.clock()
        data = self._read_available()
        if data:  # bytes arrived after all: they are not a timeout
            self._process(data, self.clock())
            return
        self._execute(self.parser.on_idle(now_s), now_s)

    def next_due_s(self) -> float | None:
        """When the line next needs attention: a held reply falls due or a partial frame would
        time out. None when nothing is pending."""
        candidates = [t for t in (self.parser.idle_deadline_s,) if t is not None]
        if self._pending:  # (a reply off the wire reaches the host after the adapter's delay:
            # no need to wake when it leaves the wire, `_process` sorts out a collision)
            candidates.append(self._pending[0][0] + self.adapter_latency_s)
        if self._in_adapter:
            candidates.append(self._in_adapter[0][0])
        return min(candidates) if candidates else None

    def flush_due(self) -> None:
        """Write the held replies whose time has come (through the adapter's delay, if any)."""
        if not self._pending and not self._in_adapter:
            return
        now_s = self.clock()
        off_wire = _take_due(self._pending, now_s)
        if self.adapter_latency_s:
            self._in_adapter += [(due + self.adapter_latency_s, p) for due, p in off_wire]
            off_wire = _take_due(self._in_adapter, now_s)
        if off_wire:
            self._write([packet for _, packet in off_wire])

    def drain(self) -> None:
        """Handle everything readable right now, without waiting; then flush due replies."""
        while True:
            data = self._read_available()
            if not data:
                break
            self._process(data, self.clock())
        self.flush_due()

    @property
    def holds_reads(self) -> bool:
        """Read instructions wait for `release_held_reads()` (see `hold_reads`)."""
        return bool(self._held_reads)

    def release_held_reads(self) -> None:
        """Answer the read instructions held back (see `hold_reads`), in their order."""
        held, self._held_reads = self._held_reads, []
        self._execute(held, self.clock())

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self._pty.close()

    def __enter__(self) -> DynamixelLine:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ---------------------------------------------------------------- internals

    def _read_available(self) -> bytes:
        data = self._pty.read_available(_READ_CHUNK_BYTES)
        self.stats.bytes_in += len(data)
        return data

    def _process(self, data: bytes, now_s: float) -> None:
        if self._pending:  # the host is talking: replies not yet on the wire collide
            if self.adapter_latency_s:  # (those off the wire already are in the adapter)
                self._in_adapter += [
                    (due + self.adapter_latency_s, p) for due, p in _take_due(self._pending, now_s)
                ]
            self.stats.replies_discarded += len(self._pending)
            self._pending.clear()
        packets = self.parser.feed(data, now_s)
        if self.hold_reads:
            self._held_reads += [p for p in packets if p.instruction in _READS]
            packets = [p for p in packets if p.instruction not in _READS]
        self._execute(packets, now_s)

    def _execute(self, packets: list[ParsedPacket], now_s: float) -> None:
        if not packets:
            return
        needs_speed = self.realtime or self.chain.enforce_baud
        line_baud = self.line_baud_bps if needs_speed else None
        outgoing: list[bytes] = []
        for packet in packets:
            replies = self.chain.handle(packet, now_s, line_baud_bps=line_baud)
            if self.realtime:
                self._pending.extend(replies)
            else:
                outgoing.extend(reply for _, reply in replies)
        if outgoing:
            self._write(outgoing)  # one syscall: the host sees the whole batch at once
        if self.realtime:
            self._pending.sort(key=lambda reply: reply[0])
            self.flush_due()

    def _write(self, packets: list[bytes]) -> None:
        view = memoryview(b"".join(packets))
        while view:
            written = self._pty.write(view)
            if not written:
                self.stats.replies_overflowed += len(packets)  # host not reading: dropped
                return
            view = view[written:]
            self.stats.bytes_out += written
        self.stats.replies_sent += len(packets)


def _take_due(queue: list[Reply], now_s: float) -> list[Reply]:
    """Remove and return the leading entries of a time-ordered queue that are due."""
    count = 0
    for due_s, _ in queue:
        if due_s > now_s:
            break
        count += 1
    taken = queue[:count]
    del queue[:count]
    return taken


def request_realtime_scheduling(priority: int = 10) -> bool:
    """Ask for SCHED_FIFO at `priority` for this process; True if granted.

    An emulator answers like hardware only if it runs when a byte arrives. On a shared machine
    (and with dynamixel-sdk busy-waiting a whole core) a normal-priority emulator is now and
    then descheduled for milliseconds; measured on the 2-core VM under load, the ping round
    trip p99 fell from ~4-5 ms to ~0.1-2 ms with SCHED_FIFO (nice -15 did not help). The loop
    blocks in select and never spins, and the kernel's RT throttling bounds it anyway. Needs
    CAP_SYS_NICE (or root); without it nothing changes and this returns False.
    """
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (AttributeError, OSError):
        return False
    return True


def serve_forever(
    line: DynamixelLine,
    stop: threading.Event | None = None,
    *,
    max_wait_s: float = 0.05,
    on_tick: Callable[[], None] | None = None,
) -> None:
    """Run `line` until `stop` is set (checked at least every `max_wait_s`).

    `on_tick()` (optional) runs once per loop turn, e.g. a stand-in firmware or command pipe.
    """
    fd = line.fileno()
    while stop is None or not stop.is_set():
        due_s = line.next_due_s()
        timeout_s = max_wait_s
        if due_s is not None:
            timeout_s = min(max_wait_s, max(0.0, due_s - line.clock()))
        readable, _, _ = select.select([fd], [], [], timeout_s)
        if readable:
            line.on_readable()
        else:
            line.on_idle()
        line.flush_due()
        if on_tick is not None:
            on_tick()
