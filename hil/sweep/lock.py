"""One sweep at a time in an output directory: an exclusive lock on `sweep.lock` in it.

Two sweeps writing one results.csv at once would each run and append every pending run (each
row twice). `locked(out_dir)` takes `fcntl.flock(LOCK_EX | LOCK_NB)` on the lock file for the
whole sweep - from before results.csv is read (what is done) until the summary is written - and
writes this process's pid into it; a second sweep is refused at once (`SweepBusy`, the CLI's
exit 2), naming the other's pid. The kernel releases the lock when its holder ends, however it
ends (SIGKILL too): a stale lock file is no obstacle. The file stays (removing it would let a
third sweep lock a new file while a second still holds the old one).
"""

from __future__ import annotations

import contextlib
import fcntl
import os
from collections.abc import Iterator
from pathlib import Path

LOCK_NAME = "sweep.lock"


class SweepBusy(RuntimeError):
    """Another sweep is writing to this output directory (the message names its pid)."""


@contextlib.contextmanager
def locked(out_dir: Path) -> Iterator[None]:
    """Hold `out_dir`'s sweep lock for the duration (module docstring)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / LOCK_NAME
    fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 64, 0).decode(errors="replace").strip() or "unknown"
            raise SweepBusy(
                f"{out_dir} is in use by another sweep (pid {holder}): two sweeps into one "
                "--out would run and write every pending run twice; wait for it to end, or "
                "give another --out"
            ) from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        yield
    finally:
        os.close(fd)  # releases the lock
