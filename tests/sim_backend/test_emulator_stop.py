"""A stopped emulator ends at once, not at the end of its idle wait.

`hil run` stops each run's emulator with SIGTERM and waits for it; the loop used to notice the
stop only when its select() timed out (up to `IDLE_WAIT_S`), which every run's end waited for.
Here the idle wait is made long enough that only a wake-up can end the loop in time.
"""

from __future__ import annotations

import threading
import time

import pytest

from sim_backend import server
from sim_backend.server import EmulatedJointSpec, Emulator, EmulatorSpec

pytestmark = pytest.mark.timeout(60)

LONG_IDLE_WAIT_S = 30.0


def _idle_emulator() -> Emulator:
    """One joint whose CAN node sends no heartbeat: with nothing due, only a stop() or the
    idle wait ends the loop's select()."""
    joint = EmulatedJointSpec(dxl_id=1, encoder_node_id=5)
    return Emulator(EmulatorSpec(joints=(joint,), heartbeat_ms=0))


def _loop_ended_after_a_stop(*, before_run: bool) -> bool:
    """Run an idle emulator's loop in a thread and stop it, before it starts or once it waits
    in select(); True if the loop ended within half the (long) idle wait."""
    emulator = _idle_emulator()
    thread = threading.Thread(target=emulator.run, daemon=True)
    try:
        if before_run:
            emulator.stop()
        thread.start()
        if not before_run:
            time.sleep(0.2)  # in its select() by now: nothing is due on an idle bus
            emulator.stop()
        thread.join(LONG_IDLE_WAIT_S / 2)
        return not thread.is_alive()
    finally:
        emulator.stop()
        thread.join(LONG_IDLE_WAIT_S + 5)
        emulator.close()


def test_stop_wakes_the_loop_out_of_its_idle_wait(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(server, "IDLE_WAIT_S", LONG_IDLE_WAIT_S)
    assert _loop_ended_after_a_stop(before_run=False), "the loop slept through stop()"


def test_a_stop_before_run_ends_it_at_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """The host's SIGTERM can come right after the endpoints line, before `serve()` enters the
    loop: run() must not start as if nothing had been asked (the host then waited 5 s and
    killed the emulator, and its fault counts were lost)."""
    monkeypatch.setattr(server, "IDLE_WAIT_S", LONG_IDLE_WAIT_S)
    assert _loop_ended_after_a_stop(before_run=True), "a stop before run() was forgotten"
