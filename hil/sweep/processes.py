"""Shutting down a Ray that this process started, with nothing left behind.

`ray.shutdown()` ends the processes Ray's driver started itself (GCS, raylet); the raylet's own
children (dashboard and runtime-env agents, workers) are meant to notice their parent's end
and exit. On a loaded 2-core machine two agents were seen still running more than three
minutes after a Ctrl-C'd sweep. So the sweep notes every descendant of this process before it
shuts Ray down (those that were there before Ray started excepted), gives them `grace_s` to
leave on their own, then sends SIGTERM and, after `grace_s` more, SIGKILL to any that remain.

An agent whose raylet died first (a raylet may handle SIGINT itself) would be reparented to
init and no longer be found below this process: `adopt_orphans()`, called before Ray starts,
makes this process their "child subreaper" (Linux prctl), so orphans below it come to it
instead.

Processes are found through /proc (Linux); elsewhere only `ray.shutdown()` runs. A process is
known by its pid and start time, so a pid reused meanwhile is never signalled.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

PROC = Path("/proc")
GRACE_S = 5.0
PR_SET_CHILD_SUBREAPER = 36  # linux/prctl.h

ProcessId = tuple[int, int]  # (pid, start time in clock ticks since boot)


def _stat(pid: int) -> tuple[int, int] | None:
    """(parent pid, start time) of a live process, None if it is gone (or a zombie)."""
    try:
        text = (PROC / str(pid) / "stat").read_text()
    except OSError:
        return None
    # the command name (field 2) may hold spaces and parentheses: split after its last ')'
    fields = text[text.rindex(")") + 2 :].split()
    if fields[0] == "Z":
        return None
    return int(fields[1]), int(fields[19])


def descendants(root: int) -> set[ProcessId]:
    """Every live process below `root` (children, their children, ...)."""
    if not PROC.is_dir():
        return set()
    parents: dict[int, list[tuple[int, int]]] = {}
    for entry in PROC.iterdir():
        if entry.name.isdigit() and (stat := _stat(int(entry.name))) is not None:
            parents.setdefault(stat[0], []).append((int(entry.name), stat[1]))
    found: set[ProcessId] = set()
    frontier = [root]
    while frontier:
        for child in parents.get(frontier.pop(), []):
            if child not in found:
                found.add(child)
                frontier.append(child[0])
    return found


def _alive(processes: set[ProcessId]) -> set[ProcessId]:
    return {p for p in processes if (stat := _stat(p[0])) is not None and stat[1] == p[1]}


def _never() -> bool:
    return False


def _wait_gone(
    processes: set[ProcessId], seconds: float, hurry: Callable[[], bool] = _never
) -> set[ProcessId]:
    deadline = time.monotonic() + seconds
    while (left := _alive(processes)) and time.monotonic() < deadline and not hurry():
        time.sleep(0.1)
    return left


def adopt_orphans() -> bool:
    """Become the child subreaper of everything below this process (Linux); False where that
    is not possible."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def end_processes(
    processes: set[ProcessId], grace_s: float = GRACE_S, hurry: Callable[[], bool] = _never
) -> set[ProcessId]:
    """Wait, then SIGTERM, then SIGKILL; returns the processes still alive at the end (an
    ended process may stay a zombie until its parent reaps it; it is not alive). Once
    `hurry()` is true the waits before SIGTERM and SIGKILL are cut short (a second Ctrl-C)."""
    left = _wait_gone(processes, grace_s, hurry)
    for sig in (signal.SIGTERM, signal.SIGKILL):
        for pid, _ in left:
            with contextlib.suppress(OSError):  # gone meanwhile, or not ours to signal
                os.kill(pid, sig)
        # SIGKILL is not refused: the wait after it is only for the kernel to end them
        left = _wait_gone(left, grace_s, _never if sig == signal.SIGKILL else hurry)
    return left


def shutdown_ray_started_here(
    ray: Any, before: set[ProcessId], grace_s: float = GRACE_S, hurry: Callable[[], bool] = _never
) -> set[ProcessId]:
    """ray.shutdown(), then end every process below this one that was not there `before` Ray
    started (`descendants(os.getpid())` taken then); returns any that would not end. Also
    after a start cut short (Ray not initialised, some of its processes running)."""
    started = descendants(os.getpid()) - before
    ray.shutdown()
    return end_processes(started, grace_s, hurry)
