"""The loop's judgement of the log writer (hil/output/writer_watch.py), on a fake clock and a
fake /proc: a writer asleep at every look that goes on looking at the pipe is waiting for the
loop, not stalled; one that stops looking is stalled ~0.6 s after its last progress.

Before: only the records handled counted as progress, and a writer polling an empty pipe on a
loaded machine (asleep at every look) was once judged stalled mid-run of a comparison with one
record owed, the run stopped as on a lost bus."""

from __future__ import annotations

from drivers.peer_wait import PeerLook
from hil.output.writer_watch import WRITER_IDLE_WINDOW_S, WRITER_STALL_S, StallWatch


class FakeClock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


class Asleep:
    """A process asleep at every look, using no CPU."""

    def look(self) -> PeerLook:
        return PeerLook(runnable=False, cpu_s=0.0, state="asleep")


def run_watch(*, keeps_looking: bool, seconds: float = 3.0) -> float | None:
    """When the watch says stalled (None: never), the writer owing one record throughout and
    the loop checking every 5 ms."""
    clock = FakeClock()
    watch = StallWatch(1234, Asleep(), clock=clock)
    looks = 0
    while clock.now < seconds:
        if keeps_looking:
            looks += 1
        if watch.check(done=10, owed=1, looks=looks):
            return clock.now
        clock.now += 0.005
    return None


def test_a_writer_that_keeps_looking_at_the_pipe_is_not_stalled() -> None:
    assert run_watch(keeps_looking=True) is None


def test_a_writer_that_stops_looking_is_stalled_after_the_window() -> None:
    stalled_at = run_watch(keeps_looking=False)
    assert stalled_at is not None
    assert WRITER_STALL_S <= stalled_at <= WRITER_STALL_S + WRITER_IDLE_WINDOW_S + 0.05
