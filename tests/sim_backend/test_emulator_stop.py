"""A stopped emulator ends at once, not at the end of its idle wait.

`hil run` stops each run's emulator with SIGTERM and waits for it; the loop used to notice the
stop only when its select() timed out (up to `IDLE_WAIT_S`), which every run's end waited for.
Here the idle wait is made long enough that only a wake-up can end the loop in time.
"""

from __future__ import annotations

import select
import threading
import time
import types

import pytest

from sim_backend import server
from sim_backend.server import EmulatedJointSpec, Emulator, EmulatorSpec

pytestmark = pytest.mark.timeout(60)

LONG_IDLE_WAIT_S = 30.0
MAX_IDLE_WAKE_UPS = 3  # the stale wake-up, then the long wait (a spinning loop: thousands)


def _idle_emulator() -> Emulator:
    """One joint whose CAN node sends no heartbeat: with nothing due, only a stop() or the
    idle wait ends the loop's select()."""
    joint = EmulatedJointSpec(dxl_id=1, encoder_node_id=5)
    return Emulator(EmulatorSpec(joints=(joint,), heartbeat_ms=0))


def _running_emulator() -> tuple[Emulator, threading.Thread]:
    emulator = _idle_emulator()
    thread = threading.Thread(target=emulator.run, daemon=True)
    thread.start()
    time.sleep(0.2)  # in its select() by now: nothing is due on an idle bus
    return emulator, thread


def test_stop_wakes_the_loop_out_of_its_idle_wait(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(server, "IDLE_WAIT_S", LONG_IDLE_WAIT_S)
    emulator, thread = _running_emulator()
    try:
        emulator.stop()
        thread.join(LONG_IDLE_WAIT_S / 2)
        assert not thread.is_alive(), "the loop slept through stop() to its idle timeout"
    finally:
        emulator.stop()
        thread.join(LONG_IDLE_WAIT_S + 5)
        emulator.close()


def test_a_stop_before_run_does_not_leave_the_loop_spinning(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The wake-up byte of a stop() that came before run() is taken once, not seen forever."""
    monkeypatch.setattr(server, "IDLE_WAIT_S", LONG_IDLE_WAIT_S)
    waits = []

    def counted_select(*args: object) -> object:
        waits.append(args)
        return select.select(*args)

    monkeypatch.setattr(server, "select", types.SimpleNamespace(select=counted_select))
    emulator = _idle_emulator()
    try:
        emulator.stop()
        thread = threading.Thread(target=emulator.run, daemon=True)
        thread.start()
        time.sleep(0.5)
        assert len(waits) <= MAX_IDLE_WAKE_UPS, f"{len(waits)} select() calls in 0.5 s, idle"
    finally:
        emulator.stop()
        thread.join(5)
        emulator.close()
