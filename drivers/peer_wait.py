"""How long to wait for a device that is a process on this machine: `PeerWait`.

On hardware every wait of the drivers has a fixed allowance: a device answers within its
timing or not at all. An emulator in lock-step is a process on the same machine, and a loaded
machine delays its answers by as long as the scheduler keeps it from a CPU (2 of 10 runs at
once on 2 cores lost a PING at bus open to a 102 ms allowance): a run whose waits expired on
such a delay would depend on the machine's load. So a wait that has used its allowance asks
what the process is doing (`PeerActivity`, observed by whoever knows the process: hil/wiring),
and goes on while it works:

    working     runnable at a look (running, waiting for a CPU, or in uninterruptible I/O),
                or it used more than BUSY_CPU_SHARE of the time since the idle stretch began:
                the wait is extended by LOOK_INTERVAL_S and it is looked at again then
    idle        neither, at every look for `idle_window_s` in a row (stopped by SIGSTOP or a
                debugger, ended, or asleep with nothing to do - a silent device, a request it
                dropped): the wait ends, as on hardware

A dead or stopped peer therefore costs its allowance plus one idle window, a slow one is
waited for. A peer that works and never answers (a bug: it spins) is given up on after
`max_extension_s`, so that a wait cannot become a hang.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

LOOK_INTERVAL_S = 0.002  # how often a working peer is looked at again
IDLE_WINDOW_S = 0.010  # the emulator: idle this long after the allowance, and it has no answer
# A peer asleep at every look but that used this share of the time since (it ran between the
# looks) is working. An idle emulator wakes for its nodes' heartbeats: ~1 % of a CPU.
BUSY_CPU_SHARE = 0.25
MAX_EXTENSION_S = 60.0  # a peer that works this long past the allowance without answering


@dataclass(frozen=True)
class PeerLook:
    """One look at a process: whether it can run now, and the CPU time it has used [s]."""

    runnable: bool
    cpu_s: float
    state: str  # what it is doing, in words (for messages)


class PeerActivity(Protocol):
    """What the process behind a bus is doing now; None when that cannot be told (it has
    ended, or the OS does not say): a wait then ends at its allowance."""

    def look(self) -> PeerLook | None: ...


class PeerWait:
    """The extensions of one wait after its allowance (see the module docstring). `begin()`
    when a new wait starts (it looks at nothing); `extension_s()` each time its allowance or
    the last extension has run out: the seconds to wait on, 0.0 to stop waiting."""

    def __init__(
        self,
        activity: PeerActivity,
        *,
        idle_window_s: float = IDLE_WINDOW_S,
        look_interval_s: float = LOOK_INTERVAL_S,
        max_extension_s: float = MAX_EXTENSION_S,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        if not (idle_window_s > 0 and look_interval_s > 0 and max_extension_s > 0):
            raise ValueError("the idle window, look interval and maximum must be > 0 s")
        self.activity = activity
        self.idle_window_s = idle_window_s
        self.look_interval_s = look_interval_s
        self.max_extension_s = max_extension_s
        self._clock = clock
        self.last_look: PeerLook | None = None
        self.extended_s = 0.0  # how long past its allowance the current wait went
        self.begin()

    def begin(self) -> None:
        self._first_look_s: float | None = None
        self._idle_since_s: float | None = None
        self._idle_cpu_s = 0.0
        self._given_up = False
        self.extended_s = 0.0

    def extension_s(self) -> float:
        if self._given_up:
            return 0.0
        look = self.activity.look()
        self.last_look = look
        now = self._clock()
        if self._first_look_s is None:
            self._first_look_s = now
        self.extended_s = now - self._first_look_s
        if look is None or self.extended_s >= self.max_extension_s:
            self._given_up = True
            return 0.0
        idle_since = self._idle_since_s
        working = look.runnable or (
            idle_since is not None and self._ran_since_idle(look, now - idle_since)
        )
        if working or idle_since is None:  # an idle stretch may start (again) from here
            self._idle_since_s, self._idle_cpu_s = now, look.cpu_s
            return self.look_interval_s
        if now - idle_since < self.idle_window_s:
            return self.look_interval_s
        self._given_up = True
        return 0.0

    def _ran_since_idle(self, look: PeerLook, elapsed_s: float) -> bool:
        return look.cpu_s - self._idle_cpu_s > BUSY_CPU_SHARE * max(elapsed_s, 1e-9)
