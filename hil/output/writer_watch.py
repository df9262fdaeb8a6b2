"""How the loop tells a slow log writer from a stalled one: the progress the writer reports
(`WriterProgress`) and the loop's judgement of it (`StallWatch`).

The writer (hil/output/log_process.py) counts the records it has handled - a tick's rows, an
event - and after each one says so in a page of memory it shares with the loop, with how many
bytes of log.csv, events.jsonl and timing.csv are whole on disk then: what the loop needs to
take the record over exactly where the writer stopped. Two copies of those figures alternate, so
the one the count names is always whole, even in a writer killed while it wrote the other.

A writer has stalled when, while it had records to handle, it made no progress (handled no
record and did not look at the pipe, which a working writer does every POLL_S) for
WRITER_STALL_S of the loop's wall time and then, looked at (a `PeerActivity`: the loop passes
hil/wiring/process_activity.py's look at /proc; the policy is drivers/peer_wait.py's), neither
ran nor waited for a CPU for WRITER_IDLE_WINDOW_S more: stopped (SIGSTOP, Ctrl-Z), or stuck in
the kernel on a disk that does not take its writes (a hung NFS mount or USB disk). So a stall is
found within ~0.6 s of the writer's last record, by its progress and not by how many ticks it is
behind: a writer that is slow but works (a loaded machine: runnable, waiting for a CPU) is
waited for, up to drivers.peer_wait.MAX_EXTENSION_S without a record. Without a look (none
passed, or no /proc) a writer is stalled after WRITER_STALL_S without progress. The watch's
clock runs only while the loop looks: a loop that was itself away (its process stopped, a tick
far too long) starts it again.
"""

from __future__ import annotations

import enum
import mmap
import time
from collections.abc import Callable

from drivers.peer_wait import PeerActivity, PeerWait
from hil.output.runlog import FileSizes

WRITER_STALL_S = 0.5  # no record handled for this long while it had some: look at it
WRITER_IDLE_WINDOW_S = 0.1  # ...and then neither running nor runnable for this long: stalled
_LOOK_INTERVAL_S = 0.01  # a writer that works is looked at again this often

_FIGURES = 4  # records handled, log.csv, events.jsonl, timing.csv bytes
# the page: publications, status, the writer's looks at the pipe, two copies of the figures
_COUNT, _STATUS, _LOOKS, _FIRST = 0, 1, 2, 3


class WriterStatus(enum.IntEnum):
    """What the writer says of itself besides its figures."""

    WRITING = 0
    WRITE_FAILED = 1  # a write of the record failed (the disk is full): it has ended


class WriterProgress:
    """The page the writer reports its progress in (made before the fork; see the module
    docstring)."""

    def __init__(self) -> None:
        self._map = mmap.mmap(-1, mmap.PAGESIZE)  # anonymous and shared with the child
        self._values = memoryview(self._map).cast("q")

    def publish(self, records: int, sizes: FileSizes) -> None:
        """The writer: `records` handled, the files whole to `sizes`."""
        values = self._values
        count = values[_COUNT] + 1
        base = _FIRST + _FIGURES * (count % 2)
        values[base] = records
        values[base + 1], values[base + 2], values[base + 3] = sizes
        values[_COUNT] = count  # the copy just written is the one this count names

    def looked(self) -> None:
        """The writer: it has looked at the pipe (it is alive, whether or not a whole record
        was there for it)."""
        self._values[_LOOKS] += 1

    def looks(self) -> int:
        return self._values[_LOOKS]

    def records_done(self) -> int:
        values = self._values
        return values[_FIRST + _FIGURES * (values[_COUNT] % 2)]

    def read(self) -> tuple[int, FileSizes]:
        """Records handled and the files' whole sizes (of a writer that has ended)."""
        values = self._values
        base = _FIRST + _FIGURES * (values[_COUNT] % 2)
        return values[base], FileSizes(values[base + 1], values[base + 2], values[base + 3])

    @property
    def status(self) -> WriterStatus:
        return WriterStatus(self._values[_STATUS])

    @status.setter
    def status(self, status: WriterStatus) -> None:
        self._values[_STATUS] = int(status)

    def close(self) -> None:
        self._values.release()
        self._map.close()


class StallWatch:
    """The loop's judgement of the writer's progress (see the module docstring): `check` each
    time the loop hands something over or waits for an answer."""

    def __init__(
        self,
        pid: int,
        activity: PeerActivity | None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.pid = pid
        self._clock = clock
        self._peer = (
            PeerWait(
                activity,
                idle_window_s=WRITER_IDLE_WINDOW_S,
                look_interval_s=_LOOK_INTERVAL_S,
                clock=clock,
            )
            if activity is not None
            else None
        )
        self._seen = (-1, -1)  # the records handled and the writer's looks at the last check
        self._since = 0.0  # when it last made progress (or the watch started again)
        self._last_check = -1e9
        self._next_look = 0.0

    def check(self, done: int, owed: int, looks: int = 0) -> bool:
        """True when the writer has stalled: `done` records handled, `owed` more it has,
        `looks` at the pipe so far. A writer that goes on looking at the pipe has not stalled
        whatever it owes: what it lacks has not reached the pipe (on a loaded machine a
        writer asleep between its looks is what a look at /proc sees nearly every time)."""
        now = self._clock()
        away = now - self._last_check > WRITER_STALL_S / 2
        self._last_check = now
        seen = (done, looks)
        if seen != self._seen or owed <= 0 or away:
            self._seen, self._since, self._next_look = seen, now, 0.0
            if self._peer is not None:
                self._peer.begin()
            return False
        if now - self._since < WRITER_STALL_S or now < self._next_look:
            return False
        extension = self._peer.extension_s() if self._peer is not None else 0.0
        if extension > 0.0:
            self._next_look = now + extension
            return False
        return True

    def describe(self, owed: int) -> str:
        """What the stalled writer is doing, in words (`owed`: the records it has not
        handled)."""
        look = self._peer.last_look if self._peer is not None else None
        idle_s = self._clock() - self._since
        if look is not None and look.runnable:
            return (
                f"the log writer (process {self.pid}) is running but handled none of its "
                f"{owed} records for {idle_s:.1f} s"
            )
        state = f"{look.state}, " if look is not None else ""
        return (
            f"the log writer (process {self.pid}) has stalled: {state}no progress for "
            f"{idle_s:.1f} s with {owed} records to write"
        )
