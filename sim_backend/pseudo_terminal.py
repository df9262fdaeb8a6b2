"""A pseudo-terminal an emulated device answers on: the host opens `path` as a serial port.

Facts this relies on (measured on Linux): a fresh pty is in cooked mode
(echo, CR/LF mapping, line buffering), so the device side puts it in raw mode itself; the master
gets EIO/HUP whenever no slave fd is open - which happens each time a host closes and reopens the
port (dynamixel-sdk does on every setBaudRate) - so the device keeps its own slave fd open for its
whole life; the master is non-blocking so a single-threaded event loop never stalls on it.
"""

from __future__ import annotations

import contextlib
import errno
import os
import termios
import tty


class RawPty:
    """Both ends of a raw pty: `master_fd` for the emulator, `path` for the host."""

    def __init__(self) -> None:
        self.master_fd, self._slave_fd = os.openpty()
        tty.setraw(self._slave_fd)
        os.set_blocking(self.master_fd, False)
        self.path: str = os.ttyname(self._slave_fd)
        self.closed = False

    def termios_speed(self) -> int:
        """The speed constant the host last set on its end (termios ispeed, e.g. B57600)."""
        return termios.tcgetattr(self._slave_fd)[5]

    def read_available(self, chunk_bytes: int = 4096) -> bytes:
        """Everything the host has written so far (b"" when nothing is waiting)."""
        chunks = []
        while not self.closed:
            try:
                chunk = os.read(self.master_fd, chunk_bytes)
            except (BlockingIOError, InterruptedError):
                break
            except OSError as error:
                if error.errno in (errno.EAGAIN, errno.EIO):  # EIO: no slave open
                    break
                raise
            if not chunk:
                break
            chunks.append(chunk)
            if len(chunk) < chunk_bytes:
                break
        return b"".join(chunks)

    def write(self, data: bytes | memoryview) -> int:
        """Write what the pty takes now; returns the byte count (0 when its buffer is full)."""
        try:
            return os.write(self.master_fd, data)
        except (BlockingIOError, InterruptedError):
            return 0
        except OSError as error:
            if error.errno in (errno.EAGAIN, errno.EIO):
                return 0
            raise

    def close(self) -> None:
        """Release both ends. Safe to call twice."""
        if self.closed:
            return
        self.closed = True
        for fd in (self.master_fd, self._slave_fd):
            with contextlib.suppress(OSError):
                os.close(fd)
