"""The machine's own timing, measured beside `hil bench loop`'s wall-clock run: what no loop
running on this machine can do better than.

- `bench_idle_sleeper`: a loop that only sleeps to the control period's grid (no bus, no
  emulator): how late the machine wakes a sleeping process.
- `bench_cpu_stalls`: a process that never sleeps and reads the clock as fast as it can; every
  gap between two readings is time the CPU was taken from it (a stall). Each stall is
  attributed from the kernel's own accounting of the probing thread (Linux; elsewhere its
  source is unknown):
  - `runqueue`: the thread was runnable and the OS ran another task (its schedstat run delay
    grew by at least half the stall): the guest's own scheduler, which a real-time priority or
    a CPU of its own can remove;
  - `outside`: the thread neither waited in the runqueue nor gave the CPU up: the CPU itself
    was taken away (a hypervisor's steal, firmware interrupts, long interrupt handling), which
    nothing in the OS or the program can remove;
  - `blocked`: the thread gave the CPU up itself (a voluntary context switch): the probe's
    own, not the machine's.
A stall longer than a control cycle's slack that lands in a cycle overruns that cycle whatever
the loop does; `stalls_longer_than` counts them for the loop's measured slack.
"""

from __future__ import annotations

import dataclasses
import enum
import math
import os
import resource
import time
from collections.abc import Callable, Sequence
from contextlib import closing
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from drivers.timing import DurationStats as Distribution

STALL_RECORDED_ABOVE_S = 0.0005  # gaps shorter than this are the clock's own jitter and IRQs
ACCOUNTING_READ_ABOVE_S = 0.0001  # the thread's accounting is read after every gap this long
STALL_BOUNDS_S = (0.001, 0.002, 0.003, 0.004, 0.005)


class StallSource(enum.Enum):
    RUNQUEUE = "runqueue"
    OUTSIDE = "outside"
    BLOCKED = "blocked"
    UNKNOWN = "unknown"


@dataclass(frozen=True)
class ThreadCounters:
    run_delay_s: float  # time spent runnable but not running (NaN: not accounted here)
    voluntary_switches: int  # times the thread gave the CPU up itself


class ThreadAccounting(Protocol):
    def read(self) -> ThreadCounters: ...


class LinuxThreadAccounting:
    """This thread's run delay (/proc/thread-self/schedstat, second field, ns) and voluntary
    context switches (getrusage RUSAGE_THREAD)."""

    def __init__(self) -> None:
        self._fd = os.open("/proc/thread-self/schedstat", os.O_RDONLY)

    def read(self) -> ThreadCounters:
        run_delay_ns = int(os.pread(self._fd, 128, 0).split()[1])
        switches = resource.getrusage(resource.RUSAGE_THREAD).ru_nvcsw
        return ThreadCounters(run_delay_ns * 1e-9, switches)

    def close(self) -> None:
        os.close(self._fd)


class NoThreadAccounting:
    def read(self) -> ThreadCounters:
        return ThreadCounters(math.nan, 0)

    def close(self) -> None:
        pass


def thread_accounting() -> LinuxThreadAccounting | NoThreadAccounting:
    try:
        return LinuxThreadAccounting()
    except (OSError, AttributeError):  # no /proc, or no RUSAGE_THREAD
        return NoThreadAccounting()


@dataclass(frozen=True)
class Stall:
    at_s: float  # when it began, from the probe's start
    length_s: float
    runqueue_s: float  # of which runnable but not running (NaN: unknown)
    source: StallSource


def _source(length_s: float, runqueue_s: float, gave_up_cpu: bool) -> StallSource:
    if gave_up_cpu:
        return StallSource.BLOCKED
    if math.isnan(runqueue_s):
        return StallSource.UNKNOWN
    return StallSource.RUNQUEUE if runqueue_s >= 0.5 * length_s else StallSource.OUTSIDE


def probe_cpu_stalls(
    duration_s: float,
    *,
    clock: Callable[[], float] = time.perf_counter,
    accounting: ThreadAccounting | None = None,
) -> list[Stall]:
    """Spin for `duration_s`, reading `clock`; every gap of at least STALL_RECORDED_ABOVE_S
    between two readings is a stall. The accounting is read after every gap of at least
    ACCOUNTING_READ_ABOVE_S (and the clock read again after it, so reading it is no stall):
    a run delay can only grow while the thread is not running, that is during a gap."""
    if accounting is None:
        with closing(thread_accounting()) as own:
            return probe_cpu_stalls(duration_s, clock=clock, accounting=own)
    stalls: list[Stall] = []
    counters = accounting.read()
    start = last = clock()
    while last - start < duration_s:
        now = clock()
        gap = now - last
        if gap >= ACCOUNTING_READ_ABOVE_S:
            after = accounting.read()
            if gap >= STALL_RECORDED_ABOVE_S:
                runqueue = after.run_delay_s - counters.run_delay_s
                gave_up = after.voluntary_switches > counters.voluntary_switches
                stalls.append(Stall(last - start, gap, runqueue, _source(gap, runqueue, gave_up)))
            counters = after
            now = clock()
        last = now
    return stalls


def stalls_longer_than(stalls: Sequence[Stall], bound_s: float) -> dict[str, int]:
    """How many stalls were longer than `bound_s`, in all and by source."""
    longer = [stall for stall in stalls if stall.length_s > bound_s]
    counts = {"all": len(longer)}
    for source in StallSource:
        counts[source.value] = sum(1 for stall in longer if stall.source is source)
    return counts


def _steal_s() -> float:
    """The kernel's steal time summed over all CPUs (/proc/stat), NaN where there is none."""
    try:
        with open("/proc/stat") as stat:
            fields = stat.readline().split()
        return int(fields[8]) / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return math.nan


def bench_cpu_stalls(duration_s: float) -> dict[str, Any]:
    steal_before = _steal_s()
    stalls = probe_cpu_stalls(duration_s)
    steal_s = _steal_s() - steal_before
    lengths = np.array([stall.length_s for stall in stalls])
    return {
        "duration_s": duration_s,
        "stalls": dataclasses.asdict(Distribution.of(lengths)),
        "stalled_s": float(lengths.sum()),
        "longer_than_s": {
            str(bound): stalls_longer_than(stalls, bound) for bound in STALL_BOUNDS_S
        },
        "lengths_s": [stall.length_s for stall in stalls],
        "sources": [stall.source.value for stall in stalls],
        "steal_s_all_cpus": steal_s,
        "cpu_count": os.cpu_count(),
    }


def stall_counts_longer_than(report: dict[str, Any], bound_s: float) -> dict[str, int]:
    """`stalls_longer_than` for a `bench_cpu_stalls` report (its stalls stored as lists)."""
    stalls = [
        Stall(math.nan, length, math.nan, StallSource(source))
        for length, source in zip(report["lengths_s"], report["sources"], strict=True)
    ]
    return stalls_longer_than(stalls, bound_s)


def bench_idle_sleeper(period_s: float, ticks: int) -> dict[str, Any]:
    """A loop that only sleeps to a `period_s` grid (no bus, no emulator), for `ticks` periods:
    the machine's own wake-up lateness. A wake-up later than a control tick's slack overruns
    that tick whatever the loop does."""
    lateness = np.empty(ticks)
    origin = time.perf_counter()
    for k in range(ticks):
        deadline = origin + (k + 1) * period_s
        remaining = deadline - time.perf_counter()
        if remaining > 0:
            time.sleep(remaining)
        lateness[k] = time.perf_counter() - deadline
    return {
        "ticks": ticks,
        "lateness": dataclasses.asdict(Distribution.of(lateness)),
        "late_by_more_than_s": {
            str(bound): int(np.count_nonzero(lateness > bound)) for bound in (0.001, 0.002, 0.003)
        },
    }
