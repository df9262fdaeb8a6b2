"""Opening a Dynamixel serial port through the unmodified dynamixel-sdk, with a bounded timeout.

The SDK's `PortHandler.setPacketTimeout` waits for a reply for

    tx_time_per_byte * packet_length + 2 * LATENCY_TIMER + 2.0   [ms]

with the module constant LATENCY_TIMER = 16 ms (the FTDI default latency), i.e. >= 34 ms of
busy-wait per unanswered call (measured 34.2-34.6 ms with dynamixel-sdk on a pty). A 200 Hz
loop must not discover a missing device that way. ROBOTIS advise setting the USB-serial latency
timer to 1 ms (DynamixelSDK issues #288, #319, #116); `LowLatencyPortHandler` makes the latency
term a parameter so the timeout matches the adapter's real setting. The SDK itself stays
unmodified: this is a subclass overriding `setPacketTimeout` (and the clock it measures with,
see below).

Measured against the emulated chain (tests/drivers/test_dynamixel_faults.py), 4 Mbps, latency 1 ms:
a sync read with one silent ID costs 4.25 ms (3 IDs) / 4.84 ms (12 IDs), its timeout of
4.20 / 4.78 ms, instead of >= 34 ms with the SDK's own constant.
"""

from __future__ import annotations

import os
import select
import termios
import time
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

import serial
from dynamixel_sdk import PortHandler

from drivers.dynamixel.errors import PortGoneError
from drivers.joint_bus import BusError
from drivers.peer_wait import PeerWait

_T = TypeVar("_T")

# What a vanished port raises in the SDK's calls: pyserial's SerialException (an OSError) from
# read/write, OSError from ioctl, and termios.error (not an OSError) from tcflush.
_PORT_FAILURES = (OSError, serial.SerialException, termios.error)

USB_SERIAL_SYSFS = Path("/sys/bus/usb-serial/devices")


class LowLatencyPortHandler(PortHandler):
    """`dynamixel_sdk.PortHandler` with a configurable latency term in its packet timeout.

    timeout [ms] = tx_time_per_byte * packet_length + 2 * latency_timer_ms + timeout_margin_ms

    Same shape as the SDK's formula (which hard-codes 16 ms and 2 ms). It also measures time with
    `time.perf_counter_ns` instead of the SDK's `time.time`, so a wall-clock step (NTP) cannot
    cut a wait short or stretch it. The broadcast ping keeps the SDK's own fixed timeout
    (`setPacketTimeoutMillis`, about 0.8 s), which suits a one-off scan.

    While a reply is awaited, reads sleep in select() instead of spinning (see
    `_read_when_ready`).

    patience: for a device that is a process on this machine (an emulator in lock-step), the
    wait for a reply goes on past its timeout while that process works (drivers/peer_wait.py):
    a loaded machine delays the answer, it does not lose it. None (hardware): the timeout.

    A port that fails (adapter unplugged, emulator gone) raises `PortGoneError` from then on,
    on every call, without touching the device again; the SDK's `is_using` flag is released, so
    a later call cannot be mistaken for a busy port ("Port is in use!").

    Not thread-safe (neither is the SDK): use one port from one thread.
    """

    def __init__(
        self,
        port_name: str,
        *,
        latency_timer_ms: float = 1.0,
        timeout_margin_ms: float = 2.0,
        patience: PeerWait | None = None,
    ) -> None:
        if not latency_timer_ms > 0.0:
            raise ValueError(f"latency_timer_ms must be > 0 ms, got {latency_timer_ms!r}")
        if not timeout_margin_ms >= 0.0:
            raise ValueError(f"timeout_margin_ms must be >= 0 ms, got {timeout_margin_ms!r}")
        super().__init__(port_name)
        self.latency_timer_ms = float(latency_timer_ms)
        self.timeout_margin_ms = float(timeout_margin_ms)
        self.failure: str | None = None  # the OS error that made the port fail, once it has
        self.patience = patience
        # Bytes read ahead from the OS (see `_read_ahead`) and how far the SDK has taken them.
        self._ahead = b""
        self._position = 0

    # The SDK's port I/O, guarded: a failure is recorded once and reported as PortGoneError.
    def clearPort(self) -> None:
        self._ahead, self._position = b"", 0  # what was read ahead is input too: discarded
        self._guarded("clear", super().clearPort)

    def writePort(self, packet: list[int] | bytes) -> int:
        return self._guarded("write", super().writePort, packet)

    def readPort(self, length: int) -> bytes:
        position = self._position
        end = position + length
        if end <= len(self._ahead) and self.failure is None:  # read ahead already: no call
            self._position = end
            return self._ahead[position:end]
        return self._guarded("read", self._read_ahead, length)

    def _read_ahead(self, length: int) -> bytes:
        """Up to `length` bytes, as the SDK's non-blocking read returns them, from one read of
        everything the OS holds (after sleeping until a byte is there, see below).

        The SDK reads a status packet in two or three `readPort` calls (header, then the rest),
        each a select() and a read() on the port: 24-36 system calls for the twelve replies of
        the humanoid's sync read. Reading ahead makes it one or two; the SDK sees the same
        bytes in the same order (`clearPort` discards what was read ahead with the OS's
        buffer).

        The SDK's rxPacket calls readPort in a loop without pause until the reply is complete
        or isPacketTimeout(): with the port's non-blocking read that spins a core for the
        whole wait (~1.7 ms of a 5 ms tick at 1 ms adapter latency; 34 ms per missing ID with
        the SDK's own constant), taking the CPU that the kernel's tty work and, on one
        machine, the emulator need. Sleeping in select() returns what the spin would have
        returned (the bytes there when the wait ends, or none at the timeout), so the SDK's
        logic is unchanged. Outside a packet's timeout window, or when asked for nothing,
        it does not wait.
        """
        ahead = self._ahead[self._position :]
        if length > len(ahead):
            fileno = getattr(self.ser, "fileno", None)  # a port without one is polled as before
            if fileno is not None:
                remaining_ms = self.packet_start_time + self.packet_timeout - self.getCurrentTime()
                if remaining_ms > 0.0:
                    select.select((fileno(),), (), (), remaining_ms / 1000.0)
            # everything there, or what is missing (a non-blocking read: what there is)
            ahead += super().readPort(max(self.ser.in_waiting, length - len(ahead)))
        taken = min(length, len(ahead))
        self._ahead, self._position = ahead, taken
        return ahead[:taken]

    def getBytesAvailable(self) -> int:
        buffered = len(self._ahead) - self._position
        return buffered + self._guarded("bytes available", super().getBytesAvailable)

    def gone_error(self, operation: str) -> PortGoneError:
        """The error for an `operation` on this failed port (see `PortGoneError`)."""
        return PortGoneError(
            f"the serial port {self.port_name!r} is gone ({self.failure}): the adapter was "
            "unplugged or lost power, or the emulator stopped",
            port=self.port_name,
            reason=self.failure or "",
            operation=operation,
        )

    def _guarded(self, operation: str, call: Callable[..., _T], *args: object) -> _T:
        if self.failure is not None:
            self.is_using = False
            # Nothing is attempted on a failed port: whatever was to be sent, was not.
            raise self.gone_error("write" if operation == "clear" else operation)
        try:
            return call(*args)
        except _PORT_FAILURES as exc:
            self.is_using = False  # the SDK set it for the transaction that now cannot end
            self.failure = _describe(exc)
            raise self.gone_error(operation) from exc

    def setPacketTimeout(self, packet_length: int) -> None:  # overrides the SDK method
        self.packet_start_time = self.getCurrentTime()
        self.packet_timeout = (
            self.tx_time_per_byte * packet_length
            + 2.0 * self.latency_timer_ms
            + self.timeout_margin_ms
        )
        if self.patience is not None:
            self.patience.begin()

    def setPacketTimeoutMillis(self, msec: float) -> None:  # overrides the SDK method
        super().setPacketTimeoutMillis(msec)
        if self.patience is not None:
            self.patience.begin()

    def isPacketTimeout(self) -> bool:  # overrides the SDK method
        """The SDK's test, but a reply that `patience` says is still being worked on is
        waited for on (the window restarts for the extension it gives)."""
        if self.getTimeSinceStart() <= self.packet_timeout:
            return False
        extension_s = self.patience.extension_s() if self.patience is not None else 0.0
        if extension_s > 0.0:
            self.packet_start_time = self.getCurrentTime()
            self.packet_timeout = extension_s * 1e3
            return False
        self.packet_timeout = 0  # as the SDK: the other replies of a sync read are late too
        return True

    def getCurrentTime(self) -> float:  # overrides the SDK method
        """Milliseconds on a monotonic clock (the SDK uses wall time)."""
        return time.perf_counter_ns() / 1e6

    def packet_timeout_ms(self, packet_length: int) -> float:
        """The timeout `setPacketTimeout(packet_length)` would set, for reports and tests."""
        return (
            self.tx_time_per_byte * packet_length
            + 2.0 * self.latency_timer_ms
            + self.timeout_margin_ms
        )


def _describe(exc: BaseException) -> str:
    if isinstance(exc, termios.error) and len(exc.args) == 2:  # (errno, text), no class name
        return f"[Errno {exc.args[0]}] {exc.args[1]}"
    return f"{type(exc).__name__}: {exc}"


def sdk_accepts_baudrate(baudrate: int) -> bool:
    """True if dynamixel-sdk's PortHandler can set this rate (its whitelist in getCFlagBaud)."""
    return PortHandler("").getCFlagBaud(baudrate) > 0


def usb_latency_timer_ms(port: str, sysfs_root: Path = USB_SERIAL_SYSFS) -> int | None:
    """The USB-serial adapter's latency timer [ms] for `port`, or None if it has none.

    Linux exposes it for FTDI adapters as /sys/bus/usb-serial/devices/ttyUSBn/latency_timer.
    Symlinks such as /dev/serial/by-id/... are resolved first. A pty has no such file.
    """
    device_name = os.path.basename(os.path.realpath(port))
    latency_file = sysfs_root / device_name / "latency_timer"
    try:
        return int(latency_file.read_text().strip())
    except (OSError, ValueError):
        return None


def open_port(
    port: str,
    baudrate: int,
    *,
    latency_timer_ms: float = 1.0,
    timeout_margin_ms: float = 2.0,
    sysfs_root: Path = USB_SERIAL_SYSFS,
    patience: PeerWait | None = None,
) -> LowLatencyPortHandler:
    """Open `port` at `baudrate` through the SDK, or raise `BusError` saying what to fix.

    Refuses a rate outside the SDK's whitelist (it rejects 4.5 and 10.5 Mbps although the H54
    supports them) and an adapter whose USB latency timer is longer than `latency_timer_ms`
    (every reply would then arrive after the timeout). `patience`: see LowLatencyPortHandler.
    """
    if not sdk_accepts_baudrate(baudrate):
        raise BusError(
            f"baud rate {baudrate} bps cannot be set through dynamixel-sdk's PortHandler: its "
            "whitelist (getCFlagBaud) accepts 9600, 19200, 38400, 57600, 115200, 230400, 460800, "
            "500000, 576000, 921600, 1000000, 1152000, 2000000, 2500000, 3000000, 3500000 and "
            "4000000 only (the H54 also runs at 4.5M and 10.5M, the SDK cannot). Set the "
            "devices' Baud Rate item to a rate both support, e.g. 4000000 (index 6)."
        )
    handler = LowLatencyPortHandler(
        port,
        latency_timer_ms=latency_timer_ms,
        timeout_margin_ms=timeout_margin_ms,
        patience=patience,
    )
    try:
        # setBaudRate opens (or re-opens) the port; openPort() would first open at 1 Mbps.
        opened = handler.setBaudRate(baudrate)
    except (serial.SerialException, OSError, ValueError) as exc:
        raise BusError(
            f"cannot open serial port {port!r} at {baudrate} bps: {exc}. Check the device path "
            "(e.g. /dev/ttyUSB0 or /dev/serial/by-id/...), that you may use it (dialout group) "
            "and that no other program holds it."
        ) from exc
    if not opened:
        raise BusError(f"dynamixel-sdk refused to open {port!r} at {baudrate} bps")
    adapter_latency_ms = usb_latency_timer_ms(port, sysfs_root)
    if adapter_latency_ms is not None and adapter_latency_ms > latency_timer_ms:
        handler.closePort()
        device_name = os.path.basename(os.path.realpath(port))
        raise BusError(
            f"the USB-serial adapter of {port!r} has a latency timer of {adapter_latency_ms} ms, "
            f"longer than the configured latency_timer_ms={latency_timer_ms}: replies would "
            f"arrive after the packet timeout. Set it with `echo 1 | sudo tee "
            f"{sysfs_root / device_name / 'latency_timer'}` (or a udev rule), or raise "
            "latency_timer_ms in the configuration."
        )
    return handler
