"""The files of a run's record on disk: each line written whole or not at all, and room kept for
the record's end.

`RecordFile` is one text file of the record (log.csv, events.jsonl, timing.csv) written a line
at a time with `os.write`, its size known. A line the disk does not take whole (a full disk
takes part of it, then refuses the rest) is cut off again - the file is truncated to where the
line began - so the file never ends mid-line, and the failed write raises `RecordWriteError`,
which names the file and says why in one line ("no space left on device"). The size is what is
on disk, which is what lets another process take the file over exactly there
(hil/output/log_process.py).

`DiskReserve` is a file of RESERVE_BYTES made in the run directory when the record opens
(.record-reserve), given back when a write fails (so the end of the record - the exit path's
events, summary.json - still has room on a disk that filled up) and removed when the record is
finished. A run killed outright together with its log writer leaves it behind.
"""

from __future__ import annotations

import contextlib
import errno
import os
from pathlib import Path

RESERVE_NAME = ".record-reserve"
RESERVE_BYTES = 256 * 1024  # the end of a record: events, summary.json (a few kB each)
_NO_ROOM = (errno.ENOSPC, errno.EDQUOT)
_MODE = 0o666  # as open() makes files (less the umask)
_CLOEXEC = getattr(os, "O_CLOEXEC", 0)


class RecordWriteError(OSError):
    """A file of the run's record could not be written (the disk is full, it went away): the
    message names the file. What the file held before the failed line stays whole."""

    def __init__(self, path: Path, cause: OSError) -> None:
        why = (cause.strerror or str(cause)).lower()
        super().__init__(cause.errno, why, str(path))
        self.path = Path(path)
        self.message = f"cannot write {path}: {why}"

    @property
    def no_room(self) -> bool:
        """The disk (or the user's quota) is full."""
        return self.errno in _NO_ROOM

    def __str__(self) -> str:
        return self.message


class RecordFile:
    """One append-only file of the record (see the module docstring): `write(text)` with whole
    lines, as csv.writer calls it (or bytes: run.mcap's records). `resume_at`: open an existing
    file cut to that many bytes (what another process wrote of it), to go on from there."""

    def __init__(self, path: Path, *, resume_at: int | None = None) -> None:
        self.path = Path(path)
        if resume_at is None:
            self._fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | _CLOEXEC, _MODE)
            self.size = 0
        else:
            self._fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | _CLOEXEC, _MODE)
            os.ftruncate(self._fd, resume_at)
            os.lseek(self._fd, resume_at, os.SEEK_SET)
            self.size = resume_at

    def write(self, text: str | bytes) -> None:
        data = text.encode() if isinstance(text, str) else text
        try:
            written = os.write(self._fd, data)
            while written < len(data):  # a short write: the disk took part of it
                written += os.write(self._fd, data[written:])
        except OSError as exc:
            self._cut_back()
            raise RecordWriteError(self.path, exc) from exc
        self.size += written

    def _cut_back(self) -> None:
        """The file to where the failed line began (truncating needs no room)."""
        self.cut_to(self.size)

    def cut_to(self, size: int) -> None:
        """The file cut to `size` bytes (a record of several writes that did not all go in)."""
        with contextlib.suppress(OSError):
            os.ftruncate(self._fd, size)
            os.lseek(self._fd, size, os.SEEK_SET)
            self.size = size

    def tell(self) -> int:
        return self.size

    def flush(self) -> None:
        """Nothing is buffered here (an mcap Writer calls it)."""

    @property
    def closed(self) -> bool:
        return self._fd < 0

    def close(self) -> None:
        if self._fd >= 0:
            fd, self._fd = self._fd, -1
            with contextlib.suppress(OSError):  # nothing is buffered: every line is on disk
                os.close(fd)


class DiskReserve:
    """Room kept for the record's end (see the module docstring). `create`: make the file now
    (a record taken over from another process finds the one that process made)."""

    def __init__(self, directory: Path, *, create: bool = True) -> None:
        self.path = Path(directory) / RESERVE_NAME
        if create:
            self._make()

    def _make(self) -> None:
        try:
            fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | _CLOEXEC, _MODE)
        except OSError:
            return
        try:
            if hasattr(os, "posix_fallocate"):  # blocks of its own, not a sparse file
                os.posix_fallocate(fd, 0, RESERVE_BYTES)
            else:
                os.write(fd, bytes(RESERVE_BYTES))
        except OSError:  # no room even now: no reserve
            with contextlib.suppress(OSError):
                os.unlink(self.path)
        finally:
            os.close(fd)

    def release(self) -> None:
        """Give the room back (again: nothing)."""
        with contextlib.suppress(OSError):
            os.unlink(self.path)
