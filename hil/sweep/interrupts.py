"""Ctrl-C and SIGTERM during a sweep: noted at every moment, acted on where it is safe.

`SweepSignals` handles SIGINT and SIGTERM from the moment `run_sweep` starts to its end:
- while the plan is made (pure computation: nothing is written yet) a signal stops it at once
  (`raising()`: KeyboardInterrupt);
- from then on a signal only sets `reason`: the sweep checks it before Ray starts, once Ray is
  up, after every finished run (the runs in flight are then cancelled) - and whatever it was
  doing (reading the table, starting Ray, shutting it down, writing the findings) it finishes
  that step, so results.csv is never cut and the summary is always written for what finished;
- while Ray starts: `start_ray` holds SIGINT (`sigint_held()`: blocked in this thread, so the
  processes `ray.init` starts inherit it blocked - a terminal's Ctrl-C goes to the whole
  process group, and Ray's own processes leave it to this one, which cancels and shuts them
  down in order); one that arrives meanwhile waits, pending, and is handled when the start is
  over (it used to be ignored, and lost). `ray.init` puts in its own SIGTERM handler
  (`sys.exit`) before it starts anything: inside `while_ray_starts()` a SIGTERM during the start
  comes back as that SystemExit and is noted as the signal; ours is back after it;
- a second signal while Ray shuts down cuts the grace its processes get (`hurried`).
Outside the main thread signals cannot be handled in Python; nothing is installed then.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from types import FrameType
from typing import Any

HANDLED = (signal.SIGINT, signal.SIGTERM)


class SweepSignals:
    """The signals received during one sweep (module docstring)."""

    def __init__(self) -> None:
        self.received: list[str] = []
        self._raising = False
        self._previous: dict[int, Any] = {}

    @property
    def reason(self) -> str | None:
        """The first signal's name, None while none came."""
        return self.received[0] if self.received else None

    @property
    def hurried(self) -> bool:
        """More than one signal came: the user will not wait for the grace periods."""
        return len(self.received) > 1

    def __call__(self, signum: int, _frame: FrameType | None) -> None:
        self.note(signal.Signals(signum).name)
        if self._raising:
            raise KeyboardInterrupt(self.reason)

    def note(self, name: str) -> None:
        self.received.append(name)

    @property
    def installed(self) -> bool:
        return bool(self._previous)

    def install(self) -> None:
        if threading.current_thread() is threading.main_thread():
            for sig in HANDLED:
                self._previous[sig] = signal.signal(sig, self)

    def restore(self) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
        self._previous.clear()

    @contextlib.contextmanager
    def raising(self) -> Iterator[None]:
        """A signal (or one that already came) raises KeyboardInterrupt inside the block."""
        if self.reason is not None:
            raise KeyboardInterrupt(self.reason)
        self._raising = True
        try:
            yield
        finally:
            self._raising = False

    @contextlib.contextmanager
    def while_ray_starts(self) -> Iterator[None]:
        """Around `start_ray` (module docstring): Ray's SIGTERM exit noted, ours put back."""
        if not self.installed:
            yield
            return
        try:
            yield
        except SystemExit as exc:
            if exc.code != signal.SIGTERM:  # Ray's handler exits with the signal's number
                raise
            self.note(signal.SIGTERM.name)
        finally:
            signal.signal(signal.SIGTERM, self)  # in place of Ray's


@contextlib.contextmanager
def sigint_held() -> Iterator[None]:
    """SIGINT blocked in this thread for the block, delivered (if it came) at its end; the
    processes started meanwhile inherit it blocked (module docstring). Outside the main thread
    (no Python signal handling there) it does nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous_mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous_mask)  # a pending SIGINT: now
