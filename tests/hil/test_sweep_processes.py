"""Ending what a sweep's Ray left behind: descendants found through /proc, processes that
ignore SIGTERM killed, processes there before left alone."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from hil.sweep.processes import descendants, end_processes, shutdown_ray_started_here

pytestmark = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc")

# a child that starts a grandchild ignoring SIGTERM (as an agent that missed its raylet's end)
SPAWNER = (
    "import signal, subprocess, sys, time\n"
    "subprocess.Popen([sys.executable, '-c', "
    "'import signal, time; signal.signal(signal.SIGTERM, signal.SIG_IGN); time.sleep(60)'])\n"
    "time.sleep(60)\n"
)


def _pids(processes: set[tuple[int, int]]) -> set[int]:
    return {pid for pid, _ in processes}


def _wait_for_descendants(
    count: int, other: set[tuple[int, int]] | None = None
) -> set[tuple[int, int]]:
    """This process's descendants, not counting `other`, once there are `count` of them."""
    deadline = time.monotonic() + 10
    while True:
        found = descendants(os.getpid()) - (other or set())
        if len(found) >= count or time.monotonic() > deadline:
            return found
        time.sleep(0.05)


def test_descendants_include_grandchildren_and_end_processes_kills_the_stubborn() -> None:
    other = descendants(os.getpid())  # whatever earlier tests left running
    child = subprocess.Popen([sys.executable, "-c", SPAWNER])
    try:
        found = _wait_for_descendants(2, other)
        assert child.pid in _pids(found)
        assert len(found) == 2  # the child and its grandchild, nothing else
        left = end_processes(found, grace_s=0.3)
        assert left == set()
        child.wait(timeout=5)  # reaped here; the grandchild was reparented and reaped by init
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()


def test_a_second_signal_cuts_the_grace_short() -> None:
    other = descendants(os.getpid())
    child = subprocess.Popen([sys.executable, "-c", SPAWNER])
    try:
        found = _wait_for_descendants(2, other)
        started = time.monotonic()
        # a grace of a minute each, hurried from the start: SIGTERM, then SIGKILL, at once
        assert end_processes(found, grace_s=60.0, hurry=lambda: True) == set()
        assert time.monotonic() - started < 30.0  # not the 60 s + 60 s of the grace
        child.wait(timeout=5)
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()


class _FakeRay:
    shut_down = False

    def shutdown(self) -> None:
        self.shut_down = True  # a shutdown that leaves its process running


def test_shutdown_ends_what_started_after_and_leaves_what_was_there_before() -> None:
    there_before = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        before = descendants(os.getpid())
        started = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
        _wait_for_descendants(1, before)
        ray = _FakeRay()
        assert shutdown_ray_started_here(ray, before, grace_s=0.2) == set()
        assert ray.shut_down
        assert started.wait(timeout=5) != 0  # ended by a signal
        assert there_before.poll() is None
    finally:
        there_before.kill()
        there_before.wait()


# a process that adopts orphans, starts SPAWNER, kills it (orphaning its grandchild), then
# finds the grandchild below itself and ends it
ADOPTER = f"""
import os, subprocess, sys, time
from hil.sweep.processes import adopt_orphans, descendants, end_processes
assert adopt_orphans()
child = subprocess.Popen([sys.executable, "-c", {SPAWNER!r}])
deadline = time.monotonic() + 10
while len(descendants(os.getpid())) < 2 and time.monotonic() < deadline:
    time.sleep(0.05)
child.kill(); child.wait()
orphans = descendants(os.getpid())
print(len(orphans), flush=True)
print(len(end_processes(orphans, grace_s=0.3)), flush=True)
"""


def test_an_adopting_process_finds_its_orphaned_grandchild_and_ends_it() -> None:
    result = subprocess.run(
        [sys.executable, "-c", ADOPTER], capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 0, result.stderr
    # the grandchild (ignoring SIGTERM) was found below the adopter after its parent died
    assert result.stdout.split() == ["1", "0"], result.stdout
