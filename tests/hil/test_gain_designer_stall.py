"""A gain designer that stops making progress (issue 25): a lock-step humanoid run waited on
its pipe for ever with SIGINT ignored. Now the wait is bounded by the designer's progress: a
stopped designer ends the run as a lost helper (torque off on the exit path, the record saying
what stalled and when), Ctrl-C ends the wait at once, and the designer is gone after the run."""

from __future__ import annotations

import os
import signal
import threading
import time
from pathlib import Path

import pytest

from hil.config import load_config
from hil.loop import LockstepClock, RunRequest, StopFlag, run_experiment
from hil.loop.gain_scheduler import DESIGNER_STALL_S, GainScheduler
from hil.robots import get_experiment
from hil.vocabulary import ControllerChoice
from hil.wiring.in_process import in_process_bus
from tests.support.rig import assert_log_complete, load_run

pytestmark = [
    pytest.mark.faults,
    pytest.mark.timeout(120),
    pytest.mark.skipif(not Path("/proc/self/schedstat").exists(), reason="needs Linux's /proc"),
]

CONFIG = load_config(robot="dyros-jet")
STAND = get_experiment("stand")


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state not in ("Z", "X")


class _Designers:
    """The designer processes of the schedulers built while it is installed."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.pids: list[int] = []
        built = GainScheduler.__init__

        def recording(scheduler: GainScheduler, *args, **kwargs) -> None:
            built(scheduler, *args, **kwargs)
            self.pids.append(scheduler._worker._process.pid)  # type: ignore[attr-defined]

        monkeypatch.setattr(GainScheduler, "__init__", recording)

    def release(self) -> None:  # whatever the run did: nothing left stopped or running
        for pid in self.pids:
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)


def _run(tmp_path: Path, on_progress, stop: StopFlag | None = None):
    request = RunRequest(
        STAND,
        ControllerChoice("gc+lqr", 1.0),
        tmp_path,
        duration_s=4.0,
        on_progress=on_progress,
    )
    bus = in_process_bus(CONFIG, STAND, ())
    clock = LockstepClock(CONFIG.loop.period_s)
    result = run_experiment(CONFIG, request, bus, clock, {"test": True}, stop=stop)
    return result, load_run(tmp_path)


def test_a_stopped_designer_stops_the_run_as_a_lost_helper(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    designers = _Designers(monkeypatch)
    stopped_at: list[float] = []

    def stop_the_designer(time_s: float, _total_s: float) -> None:
        if time_s >= 1.0 and not stopped_at:
            os.kill(designers.pids[0], signal.SIGSTOP)
            stopped_at.append(time.monotonic())

    try:
        result, run = _run(tmp_path, stop_the_designer)
        took_s = time.monotonic() - stopped_at[0]
    finally:
        designers.release()
    assert run.termination.startswith("bus failure: the gain designer")
    assert "has stalled: stopped (SIGSTOP" in run.termination
    assert "waiting for the design due at tick" in run.termination
    (failure,) = run.events_of("bus_failure")
    assert "GainDesignerLost" in failure["message"]
    assert 1.0 <= failure["time_s"] < 1.2  # when: the first design due after the stop
    assert run.summary["exit"][0] == "torque off"
    assert not result.torque_off_failed
    assert_log_complete(run)
    assert took_s < DESIGNER_STALL_S + 3.0  # detected within its window (and the exit path)
    assert not _alive(designers.pids[0])  # killed, not left stopped


def test_ctrl_c_ends_a_wait_for_a_stopped_designer(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """SIGINT while the loop waits for the design of a stopped designer: the run ends as
    interrupted, through its exit path, before the stall would be declared."""
    designers = _Designers(monkeypatch)
    stop = StopFlag()
    stop.install()
    timers: list[threading.Timer] = []

    def stop_the_designer_then_interrupt(time_s: float, _total_s: float) -> None:
        if time_s >= 1.0 and not timers:
            os.kill(designers.pids[0], signal.SIGSTOP)
            timers.append(threading.Timer(0.2, os.kill, (os.getpid(), signal.SIGINT)))
            timers[0].start()

    try:
        _, run = _run(tmp_path, stop_the_designer_then_interrupt, stop)
    finally:
        for timer in timers:
            timer.cancel()
            timer.join()
        stop.restore()
        designers.release()
    assert run.termination == "interrupted: SIGINT"
    assert run.summary["exit"][0] == "torque off"
    assert_log_complete(run)
    assert 1.0 <= run.summary["ticks"] * CONFIG.loop.period_s < 1.3
    assert not _alive(designers.pids[0])  # continued, told to leave, gone
