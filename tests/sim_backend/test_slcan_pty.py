"""The emulated SLCAN adapter on a pty: the protocol byte by byte, and python-can's slcan client."""

from __future__ import annotations

import os
import random
import select
import threading
import time
from collections.abc import Iterator

import can
import pytest

from sim_backend.canbus.slcan_pty import SlcanPty, bitrate_from_btr, encode_frame

pytestmark = pytest.mark.timeout(30)


class Host:
    """The host end of the pty, driven byte by byte (raw fd, no serial library)."""

    def __init__(self, adapter: SlcanPty) -> None:
        self.adapter = adapter
        self.fd = os.open(adapter.port_path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        self.frames: list[can.Message] = []

    def command(self, text: bytes, replies: int = 1) -> bytes:
        """Send commands, let the adapter run, return the reply bytes (`replies` CR/BEL ends)."""
        os.write(self.fd, text)
        received = b""
        deadline = time.monotonic() + 2.0
        while received.count(b"\r") + received.count(b"\a") < replies:
            assert time.monotonic() < deadline, f"no reply to {text!r}; got {received!r}"
            select.select([self.adapter.fileno()], [], [], 0.01)
            self.frames += self.adapter.read_frames()
            received += self.read(wait_s=0.01)
        return received

    def read(self, wait_s: float = 0.05) -> bytes:
        data = b""
        while select.select([self.fd], [], [], wait_s)[0]:
            chunk = os.read(self.fd, 4096)
            if not chunk:
                break
            data += chunk
            wait_s = 0.01
        return data

    def close(self) -> None:
        os.close(self.fd)


@pytest.fixture
def host() -> Iterator[Host]:
    adapter = SlcanPty(bus_bitrate=1_000_000)
    endpoint = Host(adapter)
    yield endpoint
    endpoint.close()
    adapter.close()


def test_version_serial_number_and_unknown_commands(host: Host) -> None:
    assert host.command(b"V\r") == b"V1013\r"
    assert host.command(b"v\r") == b"v1013\r"
    assert host.command(b"N\r") == b"NFJH1\r"
    assert host.command(b"\r") == b"\r"  # python-can's empty "no data bitrate" command
    assert host.command(b"X\r") == b"\a"
    assert host.command(b"d1234AABB\r") == b"\a"  # CAN FD is not supported
    assert host.command(b"Z1\r") == b"\a"  # no timestamps
    assert host.command(b"Z0\r") == b"\r"


def test_channel_must_be_opened_with_a_bitrate_before_frames_flow(host: Host) -> None:
    assert host.command(b"t12320102\r") == b"\a"  # closed
    assert host.command(b"O\r") == b"\a"  # no bitrate yet
    assert host.command(b"S8\r") == b"\r"
    assert host.command(b"O\r") == b"\r"
    assert host.adapter.channel_open and host.adapter.bitrate == 1_000_000
    assert host.command(b"S6\r") == b"\a"  # bitrate only while closed
    assert host.command(b"O\r") == b"\a"  # already open
    assert host.frames == []
    assert host.command(b"t12320102\r") == b"z\r"
    assert host.command(b"T1ABCDEF08" + b"00" * 8 + b"\r") == b"Z\r"
    assert host.command(b"r7053\r") == b"z\r"
    (standard, extended, remote) = host.frames
    assert (standard.arbitration_id, bytes(standard.data), standard.is_extended_id) == (
        0x123,
        b"\x01\x02",
        False,
    )
    assert (extended.arbitration_id, extended.dlc, extended.is_extended_id) == (0x1ABCDEF0, 8, True)
    assert remote.is_remote_frame and remote.arbitration_id == 0x705 and remote.dlc == 3
    assert host.command(b"t1232010\r") == b"\a"  # data shorter than the DLC
    assert host.command(b"t12390102\r") == b"\a"  # DLC 9
    assert host.command(b"C\r") == b"\r"
    assert host.command(b"t12320102\r") == b"\a"
    assert len(host.frames) == 3


def test_bus_frames_reach_the_host_only_while_open(host: Host) -> None:
    frame = can.Message(arbitration_id=0x185, data=b"\x00\xc0\x03\x00", is_extended_id=False)
    host.adapter.send_frame(frame)
    assert host.read() == b""
    host.command(b"S8\rO\r", replies=2)
    host.adapter.send_frame(frame)
    host.adapter.send_frame(can.Message(arbitration_id=0x705, data=b"\x05", is_extended_id=False))
    assert host.read() == b"t185400C00300\rt705105\r"
    host.command(b"C\r")
    host.adapter.send_frame(frame)
    assert host.read() == b""


def test_frame_encoding() -> None:
    assert encode_frame(can.Message(arbitration_id=0x80, data=b"", is_extended_id=False)) == (
        b"t0800\r"
    )
    assert (
        encode_frame(can.Message(arbitration_id=0x1FFFFFFF, data=b"\xab", is_extended_id=True))
        == b"T1FFFFFFF1AB\r"
    )
    remote = can.Message(arbitration_id=0x705, is_remote_frame=True, dlc=1, is_extended_id=False)
    assert encode_frame(remote) == b"r7051\r"


def test_bitrate_mismatch_isolates_the_adapter_and_sets_error_flags(host: Host) -> None:
    assert host.command(b"S6\rO\r", replies=2) == b"\r\r"  # 500 kbit/s on a 1 Mbit/s bus
    assert not host.adapter.on_bus
    assert host.command(b"t12320102\r") == b"z\r"  # queued ...
    assert host.frames == []  # ... but never on the bus
    host.adapter.send_frame(can.Message(arbitration_id=0x185, data=b"\x01", is_extended_id=False))
    assert host.read() == b""
    assert host.command(b"F\r") == b"FA0\r"  # error passive + bus error
    assert host.command(b"F\r") == b"F00\r"  # cleared by reading


def test_btr_registers_set_the_bitrate(host: Host) -> None:
    assert bitrate_from_btr(0x00, 0x14) == 1_000_000
    assert bitrate_from_btr(0x00, 0x1C) == 500_000
    assert bitrate_from_btr(0x01, 0x1C) == 250_000
    assert host.command(b"s0014\rO\r", replies=2) == b"\r\r"
    assert host.adapter.on_bus
    assert host.command(b"t0800\r") == b"z\r"
    assert [f.arbitration_id for f in host.frames] == [0x080]


def test_listen_only_receives_but_refuses_to_transmit(host: Host) -> None:
    assert host.command(b"S8\rL\r", replies=2) == b"\r\r"
    assert host.command(b"t0800\r") == b"\a"
    host.adapter.send_frame(can.Message(arbitration_id=0x705, data=b"\x7f", is_extended_id=False))
    assert host.read() == b"t70517F\r"


def test_output_to_a_host_that_does_not_read_is_bounded(host: Host) -> None:
    host.command(b"S8\rO\r", replies=2)
    frame = can.Message(arbitration_id=0x185, data=bytes(8), is_extended_id=False)
    for _ in range(20_000):  # ~440 kB, far beyond the pty buffer and the adapter's FIFO
        host.adapter.send_frame(frame)
    received = b""
    while chunk := host.read(wait_s=0.05):  # the host catches up; the adapter flushes its FIFO
        received += chunk
        host.adapter.flush_output()
    lines = received.split(b"\r")
    assert lines.pop() == b""
    assert set(lines) == {b"t18580000000000000000"}  # whole frames only, none corrupted
    assert 1000 < len(lines) < 20_000  # the rest was dropped
    reply = host.command(b"F\r")
    assert reply.endswith(b"F08\r")  # data overrun reported


# --- python-can's slcan interface as the host -------------------------------------------------
def pump_adapter(adapter: SlcanPty, stop: threading.Event, echo_id: int | None = None) -> None:
    while not stop.is_set():
        select.select([adapter.fileno()], [], [], 0.005)
        for frame in adapter.read_frames():
            if echo_id is not None:
                adapter.send_frame(
                    can.Message(arbitration_id=echo_id, data=frame.data, is_extended_id=False)
                )


def test_python_can_slcan_opens_talks_and_reopens_the_same_port() -> None:
    with SlcanPty() as adapter:
        stop = threading.Event()
        pump = threading.Thread(target=pump_adapter, args=(adapter, stop, 0x581), daemon=True)
        pump.start()
        try:
            for _ in range(2):  # pyserial closes and reopens; the adapter keeps the slave open
                bus = can.Bus(
                    interface="slcan",
                    channel=adapter.port_path,
                    bitrate=1_000_000,
                    sleep_after_open=0,
                )
                try:
                    assert bus.get_version(timeout=1.0) == (10, 13)
                    assert bus.get_serial_number(timeout=1.0) == "FJH1"
                    bus.send(
                        can.Message(
                            arbitration_id=0x601, data=b"\x40\x00\x10\x00", is_extended_id=False
                        )
                    )
                    reply = bus.recv(timeout=1.0)
                    assert reply is not None
                    assert (reply.arbitration_id, bytes(reply.data)) == (0x581, b"\x40\x00\x10\x00")
                    assert adapter.channel_open and adapter.bitrate == 1_000_000
                finally:
                    bus.shutdown()
                deadline = time.monotonic() + 1.0
                while adapter.channel_open and time.monotonic() < deadline:
                    time.sleep(0.005)
                assert not adapter.channel_open  # python-can sends C on shutdown
        finally:
            stop.set()
            pump.join(timeout=2.0)


def test_encode_frame_equals_the_lawicel_line_written_out() -> None:
    """The cached heads and hexlified payloads against each line formatted from its fields."""
    rng = random.Random(3)
    for _ in range(3000):
        extended, remote = rng.random() < 0.3, rng.random() < 0.1
        identifier = rng.randrange(1 << 29) if extended else rng.randrange(1 << 11)
        if rng.random() < 0.5:  # repeated identifiers reach the cache
            identifier &= 0x1F
        dlc = rng.randrange(9)
        data = bytes(rng.randrange(256) for _ in range(dlc))
        msg = can.Message(
            arbitration_id=identifier,
            is_extended_id=extended,
            is_remote_frame=remote,
            dlc=dlc,
            data=None if remote else data,
        )
        kind = ("R" if remote else "T") if extended else ("r" if remote else "t")
        width = 8 if extended else 3
        payload = "" if remote else "".join(f"{byte:02X}" for byte in data)
        expected = f"{kind}{identifier:0{width}X}{dlc}{payload}\r".encode("ascii")
        assert encode_frame(msg) == expected
