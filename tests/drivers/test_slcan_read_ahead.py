"""python-can's slcan interface on the read-ahead serial port (drivers/canbus/read_ahead.py):
the same frames as on pyserial's own port, in far fewer system calls; pyserial's read
semantics (wait up to the timeout, in_waiting, reset) kept."""

from __future__ import annotations

import os
import select
import time

import can
import pytest
import serial

from drivers.canbus.read_ahead import ReadAheadSerial, register, slcan_read_ahead

FRAMES = 16  # the humanoid's tick: 12 link encoders + 2 force/torque sensors x 2 TPDOs


@pytest.fixture
def pty():
    controller, device = os.openpty()
    yield controller, os.ttyname(device)
    os.close(controller)
    os.close(device)


def _line(i: int) -> bytes:
    return b"t%03X8%s\r" % (0x180 + i, bytes([i] * 8).hex().upper().encode())


def test_only_slcan_channels_are_rewritten() -> None:
    kwargs = {"interface": "slcan", "channel": "/dev/ttyACM0@115200", "bitrate": 1_000_000}
    assert slcan_read_ahead(kwargs)["channel"] == "readahead:///dev/ttyACM0@115200"
    assert slcan_read_ahead(kwargs)["bitrate"] == 1_000_000
    for unchanged in (
        {"interface": "socketcan", "channel": "can0"},
        {"interface": "slcan", "channel": "spy:///dev/ttyACM0"},
        {"interface": "virtual", "channel": "x"},
    ):
        assert slcan_read_ahead(unchanged) == unchanged


def test_port_reads_back_what_was_written_and_keeps_pyserials_semantics(pty) -> None:
    controller, path = pty
    register()
    port = serial.serial_for_url(f"readahead://{path}", timeout=0.02)
    assert isinstance(port, ReadAheadSerial) and port.port == path
    try:
        os.write(controller, b"abcdef")
        time.sleep(0.01)
        assert port.read(1) == b"a"
        assert port.in_waiting == 5  # all of it was read ahead into the buffer
        assert port.read(3) == b"bcd"
        started = time.perf_counter()
        assert port.read(4) == b"ef"  # only two there: waits the timeout, as pyserial does
        assert time.perf_counter() - started >= 0.015
        os.write(controller, b"xyz")
        time.sleep(0.01)
        assert port.read(1) == b"x"
        port.reset_input_buffer()
        assert port.in_waiting == 0
    finally:
        port.close()
    with pytest.raises(serial.SerialException, match="readahead://PORT"):
        ReadAheadSerial.from_url("spy:///dev/ttyACM0")


def _receive_all(bus: can.BusABC, port: serial.Serial) -> list[can.Message]:
    received: list[can.Message] = []
    deadline = time.monotonic() + 2.0
    while len(received) < FRAMES and time.monotonic() < deadline:
        if not port.in_waiting:
            select.select((bus.fileno(),), (), (), 0.05)
        msg = bus.recv(timeout=0.0)
        if msg is not None:
            received.append(msg)
    return received


def test_python_can_gets_the_same_frames_in_fewer_system_calls(
    pty, monkeypatch: pytest.MonkeyPatch
) -> None:
    controller, path = pty
    os_reads = {"n": 0}
    real_read = os.read

    def counting_read(fd: int, n: int) -> bytes:
        os_reads["n"] += 1
        return real_read(fd, n)

    results = {}
    for kind in ("plain", "readahead"):
        kwargs = {"interface": "slcan", "channel": path, "sleep_after_open": 0, "timeout": 0.001}
        bus = can.Bus(**(slcan_read_ahead(kwargs) if kind == "readahead" else kwargs))
        try:
            time.sleep(0.01)
            while select.select((controller,), (), (), 0)[0]:
                os.read(controller, 1024)  # the adapter's set-up commands ("S8", "O")
            os.write(controller, b"".join(_line(i) for i in range(FRAMES)))
            time.sleep(0.01)
            monkeypatch.setattr(os, "read", counting_read)
            os_reads["n"] = 0
            frames = _receive_all(bus, bus.serialPortOrig)
            monkeypatch.setattr(os, "read", real_read)
            results[kind] = ([(m.arbitration_id, bytes(m.data)) for m in frames], os_reads["n"])
        finally:
            monkeypatch.setattr(os, "read", real_read)
            bus.shutdown()
    expected = [(0x180 + i, bytes([i] * 8)) for i in range(FRAMES)]
    assert results["plain"][0] == expected
    assert results["readahead"][0] == expected
    assert results["plain"][1] >= FRAMES * 20  # one system call per byte
    assert results["readahead"][1] <= 4
