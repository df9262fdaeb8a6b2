"""The pty endpoint (`DynamixelLine`) in-process with a hand-driven clock: raw mode, the kept
slave fd, reply scheduling, the byte timeout without false drops, collisions.

The host side is a plain fd on the pty slave here (no SDK: nothing busy-waits), so the test
decides exactly when bytes arrive and what time it is.
"""

from __future__ import annotations

import os
import select
import termios
import threading
import time
import tty
from collections.abc import Iterator

import pytest

from sim_backend.dynamixel.chain import DynamixelChain
from sim_backend.dynamixel.device import H54Device
from sim_backend.dynamixel.line import DynamixelLine, serve_forever
from sim_backend.dynamixel.protocol import (
    BYTE_TIMEOUT_S,
    Instruction,
    PacketParser,
    build_instruction_packet,
)

pytestmark = pytest.mark.timeout(30)

PING_1 = build_instruction_packet(1, Instruction.PING)
READ_1 = build_instruction_packet(1, Instruction.READ, bytes((0x63, 0x02, 4, 0)))


class FakeClock:
    def __init__(self) -> None:
        self.now_s = 100.0

    def __call__(self) -> float:
        return self.now_s


class Host:
    """The host end of the pty: a raw, non-blocking fd on the slave."""

    def __init__(self, path: str, *, raw: bool = True) -> None:
        self.fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        if raw:
            tty.setraw(self.fd)

    def send(self, data: bytes) -> None:
        os.write(self.fd, data)

    def receive(self, wait_s: float = 0.2) -> list[tuple[int, bytes]]:
        """Status packets that arrived: [(id, params)] (params[0] is the error byte)."""
        select.select([self.fd], [], [], wait_s)
        data = b""
        while True:
            try:
                chunk = os.read(self.fd, 4096)
            except BlockingIOError:
                break
            if not chunk:
                break
            data += chunk
        return [(p.packet_id, p.params) for p in PacketParser().feed(data, 0.0)]

    def close(self) -> None:
        os.close(self.fd)


@pytest.fixture
def clock() -> FakeClock:
    return FakeClock()


@pytest.fixture
def instant(clock: FakeClock) -> Iterator[tuple[DynamixelLine, Host]]:
    line = DynamixelLine(DynamixelChain([H54Device(1)]), clock=clock)
    host = Host(line.port_path)
    yield line, host
    host.close()
    line.close()


@pytest.fixture
def realtime(clock: FakeClock) -> Iterator[tuple[DynamixelLine, Host]]:
    line = DynamixelLine(DynamixelChain([H54Device(1)]), realtime=True, clock=clock)
    host = Host(line.port_path)
    yield line, host
    host.close()
    line.close()


def wait_readable(line: DynamixelLine) -> None:
    assert select.select([line.fileno()], [], [], 1.0)[0], "emulator saw no bytes"


def assert_passed_on_at(
    line: DynamixelLine, host: Host, clock: FakeClock, at_s: float, ids: list[int]
) -> None:
    """Nothing reaches the host a microsecond before `at_s`; the replies of `ids` at it."""
    clock.now_s = at_s - 1e-6
    line.flush_due()
    assert host.receive(wait_s=0.02) == []
    clock.now_s = at_s
    line.flush_due()
    assert [reply[0] for reply in host.receive()] == ids


def test_pty_is_raw_and_survives_the_host_closing_and_reopening(clock: FakeClock) -> None:
    with DynamixelLine(DynamixelChain([H54Device(1)]), clock=clock) as line:
        host = Host(line.port_path, raw=False)  # the emulator made it raw, not the host
        attrs = termios.tcgetattr(host.fd)
        assert not attrs[3] & (termios.ICANON | termios.ECHO)  # lflag
        assert not attrs[1] & termios.OPOST  # oflag
        host.close()  # what the SDK's setBaudRate does: close ...
        assert select.select([line.fileno()], [], [], 0.05)[0] == []  # no HUP/EIO storm
        line.on_idle()
        host = Host(line.port_path)  # ... and open again
        host.send(PING_1)
        wait_readable(line)
        line.on_readable()
        assert host.receive() == [(1, bytes((0, 0x08, 0xD3, 1)))]
        host.close()


def test_instant_mode_answers_at_once(instant: tuple[DynamixelLine, Host]) -> None:
    line, host = instant
    host.send(PING_1 + READ_1)
    wait_readable(line)
    line.on_readable()
    assert [reply[0] for reply in host.receive()] == [1, 1]
    assert line.next_due_s() is None


def test_realtime_mode_holds_replies_until_due(
    realtime: tuple[DynamixelLine, Host], clock: FakeClock
) -> None:
    line, host = realtime
    speed = termios.tcgetattr(host.fd)
    speed[4] = speed[5] = termios.B1000000
    termios.tcsetattr(host.fd, termios.TCSANOW, speed)
    assert line.line_baud_bps == 1_000_000
    host.send(READ_1)
    wait_readable(line)
    line.on_readable()
    due_s = clock.now_s + (14 + 15) * 10 / 1e6 + 250 * 2e-6
    assert line.next_due_s() == pytest.approx(due_s)
    assert host.receive(wait_s=0.02) == []
    clock.now_s = due_s - 1e-6
    line.flush_due()
    assert host.receive(wait_s=0.02) == []
    clock.now_s = due_s
    line.flush_due()
    assert [reply[0] for reply in host.receive()] == [1]
    assert line.next_due_s() is None


def test_the_usb_adapter_passes_a_reply_on_after_its_latency_timer(clock: FakeClock) -> None:
    # FTDI: a short packet waits in the adapter until the latency timer expires (1 ms set here);
    # the host talking after the reply left the wire no longer collides with it
    line = DynamixelLine(
        DynamixelChain([H54Device(1)]), realtime=True, clock=clock, adapter_latency_s=1e-3
    )
    host = Host(line.port_path)
    try:
        speed = termios.tcgetattr(host.fd)
        speed[4] = speed[5] = termios.B1000000
        termios.tcsetattr(host.fd, termios.TCSANOW, speed)
        host.send(READ_1)
        wait_readable(line)
        line.on_readable()
        wire_due_s = clock.now_s + (14 + 15) * 10 / 1e6 + 250 * 2e-6
        clock.now_s = wire_due_s
        line.flush_due()  # off the wire, into the adapter
        assert host.receive(wait_s=0.02) == []
        assert line.next_due_s() == pytest.approx(wire_due_s + 1e-3)
        assert_passed_on_at(line, host, clock, wire_due_s + 1e-3, [1])
        assert line.next_due_s() is None
    finally:
        host.close()
        line.close()
    with pytest.raises(ValueError, match="only in realtime"):
        DynamixelLine(DynamixelChain([H54Device(1)]), adapter_latency_s=1e-3)


def test_a_reply_off_the_wire_survives_the_host_talking_without_a_wake_up_between(
    clock: FakeClock,
) -> None:
    """The line wakes when a reply reaches the host (wire time + the adapter's latency), not
    when it leaves the wire; the host talking later still finds the replies that left the wire
    by then in the adapter (passed on at their time), and only those still on it collide."""
    chain = DynamixelChain([H54Device(1), H54Device(2), H54Device(3)])
    line = DynamixelLine(chain, realtime=True, clock=clock, adapter_latency_s=1e-3)
    host = Host(line.port_path)
    try:
        speed = termios.tcgetattr(host.fd)
        speed[4] = speed[5] = termios.B1000000
        termios.tcsetattr(host.fd, termios.TCSANOW, speed)
        start = clock.now_s
        host.send(build_instruction_packet(0xFE, Instruction.PING))  # all three answer
        wait_readable(line)
        line.on_readable()
        status_s = 14 * 10 / 1e6 + 250 * 2e-6  # each status: Return Delay Time + its bytes
        first_off_wire = start + 10 * 10 / 1e6 + status_s
        assert line.next_due_s() == pytest.approx(first_off_wire + 1e-3)
        clock.now_s = first_off_wire + 0.5 * status_s  # the 2nd still on the wire; no wake-up
        host.send(PING_1)  # collides with the 2nd and 3rd only
        wait_readable(line)
        line.on_readable()
        assert line.stats.replies_discarded == 2
        assert_passed_on_at(line, host, clock, first_off_wire + 1e-3, [1])
    finally:
        host.close()
        line.close()


def test_host_talking_over_held_replies_discards_them(
    realtime: tuple[DynamixelLine, Host], clock: FakeClock
) -> None:
    line, host = realtime
    host.send(READ_1)
    wait_readable(line)
    line.on_readable()
    host.send(PING_1)  # before the READ's reply was due
    wait_readable(line)
    line.on_readable()
    assert line.stats.replies_discarded == 1
    clock.now_s += 1.0
    line.flush_due()
    assert [params[1:] for _, params in host.receive()] == [bytes((0x08, 0xD3, 1))]  # ping only


def test_no_false_byte_timeout_when_the_rest_was_already_waiting(
    instant: tuple[DynamixelLine, Host], clock: FakeClock
) -> None:
    """The emulator was 'descheduled' for 10 ms between two reads; the rest of the packet was
    in the pty all along. on_idle must read it, not time the packet out."""
    line, host = instant
    host.send(READ_1[:8])
    wait_readable(line)
    line.on_readable()
    assert line.next_due_s() == pytest.approx(clock.now_s + BYTE_TIMEOUT_S)
    host.send(READ_1[8:])
    clock.now_s += 0.010
    line.on_idle()
    assert line.parser.stats.byte_timeouts == 0
    assert [reply[0] for reply in host.receive()] == [1]


def test_byte_timeout_drops_a_truncated_packet_after_real_idle(
    instant: tuple[DynamixelLine, Host], clock: FakeClock
) -> None:
    line, host = instant
    host.send(READ_1[:8])
    wait_readable(line)
    line.on_readable()
    clock.now_s += 0.5 * BYTE_TIMEOUT_S
    line.on_idle()
    assert line.parser.stats.byte_timeouts == 0
    clock.now_s += BYTE_TIMEOUT_S
    line.on_idle()
    assert line.parser.stats.byte_timeouts >= 1 and line.next_due_s() is None
    host.send(PING_1)
    wait_readable(line)
    line.on_readable()
    assert host.receive() == [(1, bytes((0, 0x08, 0xD3, 1)))]  # clean, no CRC error


def test_drain_handles_everything_waiting(instant: tuple[DynamixelLine, Host]) -> None:
    line, host = instant
    host.send(PING_1 * 3)
    wait_readable(line)  # the pty has passed the bytes on (no fixed sleep: a loaded kernel
    line.drain()  # may take longer than any), and drain() takes all that is there
    deadline = time.monotonic() + 5.0
    while line.stats.bytes_in < 3 * len(PING_1):  # the rest, if the pty passed it in pieces
        assert time.monotonic() < deadline, f"only {line.stats.bytes_in} bytes arrived"
        wait_readable(line)
        line.drain()
    assert line.stats.replies_sent == 3
    assert len(host.receive()) == 3


def test_serve_forever_stops_on_event(instant: tuple[DynamixelLine, Host]) -> None:
    line, host = instant
    line.clock = time.monotonic
    stop = threading.Event()
    worker = threading.Thread(target=serve_forever, args=(line, stop), daemon=True)
    worker.start()
    host.send(PING_1)
    assert [reply[0] for reply in host.receive(wait_s=1.0)] == [1]
    stop.set()
    worker.join(2.0)
    assert not worker.is_alive()
