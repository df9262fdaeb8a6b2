"""The loop's two clocks: lock-step (emulated testbed, deterministic) and wall clock (hardware).

Both hand out ticks on a fixed grid t_k = k * period. The wall clock keeps absolute deadlines
(no drift: a late tick does not push the later ones back), skips ticks it has missed entirely,
and records slack, measured period and overruns for every tick, as Upkie/vulp's
SynchronousClock does. The lock-step clock never waits: the virtual testbed advances exactly one
period per tick (it steps its physics on the CAN SYNC that each tick sends), so a run is
deterministic and faster than real time.
"""

from __future__ import annotations

import abc
import math
import time
from dataclasses import dataclass


@dataclass(frozen=True)
class Tick:
    """One scheduled cycle of the loop."""

    index: int  # k: the grid index (skipped ticks leave gaps)
    time_s: float  # k * period: the loop's own time base
    skipped: int  # grid ticks missed before this one (wall clock only)
    slack_s: float  # time left before the deadline when the previous cycle finished
    measured_period_s: float  # time since the previous tick started (wall clock)


class LoopClock(abc.ABC):
    def __init__(self, period_s: float) -> None:
        if not period_s > 0:
            raise ValueError(f"loop period must be > 0, got {period_s}")
        self.period_s = period_s

    @abc.abstractmethod
    def next_tick(self) -> Tick:
        """Block until the next tick is due and return it."""

    @property
    @abc.abstractmethod
    def deterministic(self) -> bool:
        """True when the tick sequence does not depend on the wall clock."""

    @abc.abstractmethod
    def start_grid(self) -> None:
        """The start-up tick (tick 0: the start gate, torque on) is over: pace from here."""


class LockstepClock(LoopClock):
    """Ticks back to back; the emulated plant's time is the tick time."""

    deterministic = True

    def __init__(self, period_s: float) -> None:
        super().__init__(period_s)
        self._index = -1

    def next_tick(self) -> Tick:
        self._index += 1
        return Tick(self._index, self._index * self.period_s, 0, math.nan, self.period_s)

    def start_grid(self) -> None:
        """No deadlines: nothing to re-anchor."""

    def now(self) -> float:
        """The current tick's time: what the drivers stamp their readings with in lock-step."""
        return max(self._index, 0) * self.period_s


@dataclass
class WallClockStats:
    ticks: int = 0
    skipped: int = 0
    overruns: int = 0  # cycles that finished after their deadline


class WallClock(LoopClock):
    """Absolute deadlines on time.perf_counter; sleeps, then spins the last `spin_s` (a period
    or more: never sleeps). Spinning keeps the CPU busy, and on a virtual machine a busy virtual
    CPU is not halted: it is woken without the hypervisor's help (docs/realtime.md)."""

    deterministic = False

    def __init__(self, period_s: float, spin_s: float = 0.0003) -> None:
        super().__init__(period_s)
        if not spin_s >= 0.0:
            raise ValueError(f"spin_s must be >= 0 s, got {spin_s!r}")
        self.spin_s = spin_s
        self.stats = WallClockStats()
        self._start: float | None = None
        self._index = -1
        self._last_start = math.nan

    def next_tick(self) -> Tick:
        now = time.perf_counter()
        if self._start is None:
            self._start = now
            self._index = 0
            self._last_start = now
            self.stats.ticks = 1
            return Tick(0, 0.0, 0, math.nan, math.nan)
        deadline = self._start + (self._index + 1) * self.period_s
        slack = deadline - now
        skipped = 0
        if slack < 0:
            self.stats.overruns += 1
            # Skip the grid ticks we have missed entirely; run the next one at once.
            missed = int(-slack // self.period_s)
            skipped = missed
            self._index += missed
            deadline = self._start + (self._index + 1) * self.period_s
        else:
            self._sleep_until(deadline)
        self._index += 1
        started = time.perf_counter()
        measured = started - self._last_start
        self._last_start = started
        self.stats.ticks += 1
        self.stats.skipped += skipped
        return Tick(self._index, self._index * self.period_s, skipped, slack, measured)

    def start_grid(self) -> None:
        """Re-anchor the grid at the end of the start-up tick: the next tick is due one period
        from now. Tick 0 runs the start gate and turns torque on, a transaction per item and
        device (~0.12 s on the humanoid's twelve actuators); judged against a 5 ms deadline it
        would count as ~25 missed deadlines at once and trip the overrun watch before the first
        control tick. The actuators hold their present position meanwhile."""
        if self._start is None:
            return
        self._start = time.perf_counter() - self._index * self.period_s

    @property
    def grid_origin_s(self) -> float:
        """perf_counter of grid time 0 (tick k is due at grid_origin_s + k * period)."""
        return math.nan if self._start is None else self._start

    def _sleep_until(self, deadline: float) -> None:
        remaining = deadline - time.perf_counter()
        if remaining > self.spin_s:
            time.sleep(remaining - self.spin_s)
        while time.perf_counter() < deadline:
            pass
