"""The machine probes of `hil bench loop`: a stall is a gap in a spinning thread's clock
readings, attributed from the thread's own accounting (run delay, voluntary switches)."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time
from collections.abc import Iterator

import pytest

from hil.bench.machine import (
    LinuxThreadAccounting,
    Stall,
    StallSource,
    ThreadCounters,
    probe_cpu_stalls,
    stalls_longer_than,
)


class ScriptedClock:
    """Readings 10 us apart, with the jumps given at given reading numbers."""

    def __init__(self, jumps: dict[int, float]) -> None:
        self.jumps = jumps
        self.readings = 0
        self.now = 0.0

    def __call__(self) -> float:
        self.now += 10e-6 + self.jumps.get(self.readings, 0.0)
        self.readings += 1
        return self.now


class ScriptedAccounting:
    """Counters that change at given read numbers (the probe reads once before it starts and
    once after each gap of at least 0.1 ms)."""

    def __init__(self, changes: dict[int, ThreadCounters]) -> None:
        self.changes = changes
        self.reads = 0
        self.current = ThreadCounters(0.0, 0)

    def read(self) -> ThreadCounters:
        change = self.changes.get(self.reads)
        if change is not None:
            self.current = ThreadCounters(
                self.current.run_delay_s + change.run_delay_s,
                self.current.voluntary_switches + change.voluntary_switches,
            )
        self.reads += 1
        return self.current


def test_stalls_are_measured_and_attributed_as_the_accounting_says() -> None:
    # gaps: 3 ms with 2.5 ms in the runqueue; 2 ms with none; 4 ms after a voluntary switch;
    # 0.3 ms (read, not a stall); 1 ms with 0.4 ms in the runqueue (less than half)
    clock = ScriptedClock({100: 3e-3, 200: 2e-3, 300: 4e-3, 400: 0.3e-3, 500: 1e-3})
    accounting = ScriptedAccounting(
        {
            1: ThreadCounters(2.5e-3, 0),
            3: ThreadCounters(0.0, 1),
            4: ThreadCounters(0.1e-3, 0),  # the short gap's wait is not the next stall's
            5: ThreadCounters(0.4e-3, 0),
        }
    )
    stalls = probe_cpu_stalls(0.02, clock=clock, accounting=accounting)

    assert [round(stall.length_s * 1e6) for stall in stalls] == [3010, 2010, 4010, 1010]
    assert [stall.source for stall in stalls] == [
        StallSource.RUNQUEUE,
        StallSource.OUTSIDE,
        StallSource.BLOCKED,
        StallSource.OUTSIDE,
    ]
    assert stalls[0].runqueue_s == pytest.approx(2.5e-3)
    assert stalls[3].runqueue_s == pytest.approx(0.4e-3)
    # reading the accounting after a gap is not counted as the next gap
    assert all(stall.at_s > 0 for stall in stalls)
    counts = stalls_longer_than(stalls, 2.5e-3)
    assert counts == {"all": 2, "runqueue": 1, "outside": 0, "blocked": 1, "unknown": 0}


def test_without_accounting_the_source_is_unknown() -> None:
    class Nothing:
        def read(self) -> ThreadCounters:
            return ThreadCounters(float("nan"), 0)

    stalls = probe_cpu_stalls(0.01, clock=ScriptedClock({50: 2e-3}), accounting=Nothing())
    assert [stall.source for stall in stalls] == [StallSource.UNKNOWN]


linux_accounting = pytest.mark.skipif(
    not os.path.exists("/proc/thread-self/schedstat") or not hasattr(os, "sched_setaffinity"),
    reason="needs Linux's per-thread schedstat and CPU affinity",
)


def _stalled_s(stalls: list[Stall], source: StallSource) -> float:
    return sum(stall.length_s for stall in stalls if stall.source is source)


@pytest.fixture
def one_cpu() -> Iterator[int]:
    """This thread on one CPU for the test, its affinity restored after."""
    before = os.sched_getaffinity(0)
    cpu = min(before)
    os.sched_setaffinity(0, {cpu})
    try:
        yield cpu
    finally:
        os.sched_setaffinity(0, before)


@linux_accounting
@pytest.mark.timing
def test_another_task_on_the_same_cpu_shows_as_runqueue_stalls(one_cpu: int) -> None:
    hog = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        os.sched_setaffinity(hog.pid, {one_cpu})
        time.sleep(0.05)
        stalls = probe_cpu_stalls(1.0)
    finally:
        hog.kill()
        hog.wait()
    # two CPU-bound tasks on one CPU take turns in slices of milliseconds
    assert _stalled_s(stalls, StallSource.RUNQUEUE) > 0.2, stalls[:10]


@linux_accounting
@pytest.mark.timing
def test_a_thread_holding_the_gil_shows_as_blocked_stalls() -> None:
    done = threading.Event()

    def spin() -> None:
        while not done.is_set():
            pass

    other = threading.Thread(target=spin, daemon=True)
    other.start()
    try:
        stalls = probe_cpu_stalls(0.5)
    finally:
        done.set()
        other.join()
    # the interpreter hands the GIL over every switch interval (5 ms): the probe waits for it
    assert _stalled_s(stalls, StallSource.BLOCKED) > 0.1, stalls[:10]


@linux_accounting
def test_the_linux_accounting_counts_this_threads_sleep_as_a_voluntary_switch() -> None:
    accounting = LinuxThreadAccounting()
    try:
        before = accounting.read()
        time.sleep(0.01)
        after = accounting.read()
    finally:
        accounting.close()
    assert after.voluntary_switches > before.voluntary_switches
    assert after.run_delay_s >= before.run_delay_s >= 0.0
