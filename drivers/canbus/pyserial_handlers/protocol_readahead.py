"""`readahead://PORT`: pyserial's own serial port, reading ahead.

python-can's slcan interface reads its serial port one byte per `read(1)` call (it asks
`in_waiting` once, then calls `read(1)` that many times until the line ends). On a POSIX port
each `read(1)` is a `select()` and an `os.read()`: ~10 us, ~0.24 ms per 22-byte frame, 3.9 ms
for the 16 frames of the humanoid's tick (measured on a pty). This port answers a `read(n)`
from a buffer that one `os.read()` fills with everything the OS holds, so a frame costs one
system call, not one per byte. Reads that find nothing wait exactly as pyserial's do (up to
the port's timeout), and `in_waiting` counts the buffered bytes too, so python-can's logic runs
unchanged. Only the reading differs; writing, settings and closing are pyserial's.
"""

from __future__ import annotations

import urllib.parse

import serial

SCHEME = "readahead"


class Serial(serial.Serial):
    """pyserial's `Serial` for PORT of `readahead://PORT` (see the module docstring).

    The buffer is immutable bytes with a read position: python-can asks for one byte per call,
    so a read is a slice and an index step, not a copy of what is left."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        self._ahead = b""
        self._position = 0
        super().__init__(*args, **kwargs)

    @serial.Serial.port.setter  # type: ignore[attr-defined,misc]
    def port(self, value: str | None) -> None:
        if value is not None:
            value = self.from_url(value)
        serial.Serial.port.__set__(self, value)  # type: ignore[attr-defined]

    @staticmethod
    def from_url(url: str) -> str:
        """`readahead:///dev/ttyACM0` -> `/dev/ttyACM0` (a plain path passes unchanged)."""
        parts = urllib.parse.urlsplit(url)
        if parts.scheme and parts.scheme != SCHEME:
            raise serial.SerialException(
                f"expected {SCHEME}://PORT (e.g. {SCHEME}:///dev/ttyACM0), got {url!r}"
            )
        return url[len(SCHEME) + 3 :] if parts.scheme else url

    @property
    def in_waiting(self) -> int:
        """The bytes read ahead; only when there are none, what the OS holds (one ioctl):
        a caller that reads what this says, and asks again, sees every byte either way."""
        buffered = len(self._ahead) - self._position
        return buffered if buffered else super().in_waiting

    def read(self, size: int = 1) -> bytes:
        position = self._position
        end = position + size
        if end <= len(self._ahead):  # the common case: a byte of a frame already read ahead
            self._position = end
            return self._ahead[position:end]
        ahead = self._ahead[position:]
        waiting = super().in_waiting
        if waiting:
            ahead += super().read(waiting)  # there already: returns without waiting
        if len(ahead) < size:
            ahead += super().read(size - len(ahead))  # waits as pyserial does
        self._ahead, self._position = ahead, min(size, len(ahead))
        return ahead[:size]

    def reset_input_buffer(self) -> None:
        self._ahead, self._position = b"", 0
        super().reset_input_buffer()
