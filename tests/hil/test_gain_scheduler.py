"""The LQR's rescheduling (hil/loop/gain_scheduler.py): in lock-step a design requested at tick
k is in force from tick k + lead exactly, a contact change is designed ahead and in force on its
first tick, and the run's log is the same bytes every time; the slow walk's contacts switch at
the middle of each double support (the paper's Sec. III-C)."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from controller.humanoid import (
    WALKING_READY_LEG_ANGLES_RAD,
    LqrContact,
    SmContactRule,
    SupportState,
    lqr_contact_schedule,
)
from hil.config import load_config
from hil.experiments import WALK_SLOW
from hil.loop import build_controller, robot_model
from hil.loop.gain_scheduler import GainDesignerLost, GainScheduler
from hil.vocabulary import ControllerChoice
from tests.support.rig import run_in_process

PERIOD_S = 0.005
READY = np.array(WALKING_READY_LEG_ANGLES_RAD)
D, L, R = SupportState.DOUBLE, SupportState.LEFT, SupportState.RIGHT


class _Recorder:
    """Wraps the controller: which tick each gain was installed on."""

    def __init__(self, controller) -> None:
        self.controller = controller
        self.params = controller.params
        self.tick = 0
        self.installed: list[tuple[int, float]] = []

    def set_lqr_gain(self, gain) -> None:
        self.installed.append((self.tick, float(gain.error_gain[0, 0])))
        self.controller.set_lqr_gain(gain)


def test_lockstep_designs_are_in_force_on_their_due_tick() -> None:
    config = load_config(robot="dyros-jet")
    robot = robot_model(config)
    contacts = [LqrContact.BOTH_FEET] * 30 + [LqrContact.LEFT_FOOT] * 30
    choice = ControllerChoice("gc+lqr", 0.2)
    controller = build_controller(config, choice, PERIOD_S, robot, READY, contacts[0])
    recorder = _Recorder(controller)
    scheduler = GainScheduler(robot, recorder, PERIOD_S, 0.1, wall_clock=False)  # type: ignore[arg-type]
    lead = scheduler.lead_ticks
    try:
        for tick in range(len(contacts) - lead):
            recorder.tick = tick
            posture = READY + 1e-4 * tick
            scheduler.update(tick, posture, contacts[tick], contacts[tick + lead])
    finally:
        scheduler.close()
    ticks = [tick for tick, _ in recorder.installed]
    # the first request at tick 0 (periodic), in force at tick lead; the contact change at
    # tick 30 requested at 30 - lead and in force at 30; 20 ticks (0.1 s) later the next one
    assert ticks[0] == lead
    assert 30 in ticks
    assert ticks == sorted(ticks) and all(
        b - a >= lead for a, b in zip(ticks, ticks[1:], strict=False)
    )
    single = [gain for tick, gain in recorder.installed if tick >= 30]
    double = [gain for tick, gain in recorder.installed if tick < 30]
    assert single and double and single[0] != double[-1]  # another Sm: another gain
    assert scheduler.schedule.designs == len(ticks)
    assert scheduler.schedule.record()["compute_median_s"] > 0


def test_a_lockstep_run_with_rescheduling_writes_the_same_log(tmp_path: Path) -> None:
    config = load_config(robot="dyros-jet")
    logs = []
    for attempt in range(2):
        result, run = run_in_process(
            config, "stand", "gc+lqr+dob", tmp_path / str(attempt), duration_s=0.6, kdist=0.2
        )
        assert result.ok, result.ending
        assert run.summary["gain_schedule"]["designs"] >= 3
        logs.append((run.dir / "log.csv").read_bytes())
    assert logs[0] == logs[1]


def test_the_slow_walks_contacts_switch_at_the_middle_of_each_double_support() -> None:
    """The product's slow walk (0.8 / 3.2 s): every switch at the middle of a double support
    (the first counts the initial rest in its double support), 1.6 s after it began."""
    timeline = WALK_SLOW.pattern.timeline
    supports = [SupportState(timeline.phase(k).support.value) for k in range(timeline.n_ticks)]
    contacts = lqr_contact_schedule(supports, SmContactRule.SUPPORT_FOOT)
    switches = [k for k in range(1, len(contacts)) if contacts[k] is not contacts[k - 1]]
    runs, k = [], 0
    while k < len(supports):
        if supports[k] is D:
            start = k
            while k < len(supports) and supports[k] is D:
                k += 1
            runs.append((start, k))
        k += 1
    assert switches == [start + (end - start) // 2 for start, end in runs]
    timing = WALK_SLOW.plan.timing
    assert (timing.single_support_s, timing.double_support_s) == (0.8, 3.2)
    middle = [(end - start) // 2 * timeline.dt_s for start, end in runs[1:-1]]
    assert middle == pytest.approx([timing.double_support_s / 2] * len(middle))


def test_on_the_wall_clock_a_finished_design_is_installed_at_the_next_tick() -> None:
    import time

    config = load_config(robot="dyros-jet")
    robot = robot_model(config)
    choice = ControllerChoice("gc+lqr", 0.2)
    controller = build_controller(config, choice, PERIOD_S, robot, READY, LqrContact.BOTH_FEET)
    recorder = _Recorder(controller)
    scheduler = GainScheduler(robot, recorder, PERIOD_S, 0.1, wall_clock=True)  # type: ignore[arg-type]
    try:
        started = time.perf_counter()
        tick = 0
        while not recorder.installed and time.perf_counter() - started < 10.0:
            recorder.tick = tick
            scheduler.update(tick, READY, LqrContact.BOTH_FEET, LqrContact.BOTH_FEET)
            tick += 1
            time.sleep(0.001)  # a tick never waits for the design
    finally:
        scheduler.close()
    assert recorder.installed and recorder.installed[0][0] >= 1
    assert scheduler.schedule.record()["tick_wait_max_s"] is None  # never waited


def _scheduler(designs_on=None, wall_clock: bool = False) -> tuple[GainScheduler, _Recorder]:
    """A scheduler on the humanoid; `designs_on`: the robot model the designs use."""
    config = load_config(robot="dyros-jet")
    robot = robot_model(config)
    choice = ControllerChoice("gc+lqr", 0.2)
    controller = build_controller(config, choice, PERIOD_S, robot, READY, LqrContact.BOTH_FEET)
    recorder = _Recorder(controller)
    scheduler = GainScheduler(
        designs_on or robot,
        recorder,  # type: ignore[arg-type]
        PERIOD_S,
        0.1,
        wall_clock=wall_clock,
    )
    return scheduler, recorder


def test_the_designs_run_in_a_process_of_their_own_that_ends_with_the_scheduler() -> None:
    """A design is thousands of small calls holding the interpreter's lock: in a thread it
    delayed the loop's wake-ups by milliseconds. The worker is a child process."""
    import os

    scheduler, recorder = _scheduler()
    worker = scheduler._worker
    process = worker._process  # type: ignore[attr-defined]
    assert process.pid != os.getpid() and process.is_alive()
    for tick in range(scheduler.lead_ticks + 1):
        scheduler.update(tick, READY, LqrContact.BOTH_FEET, LqrContact.BOTH_FEET)
    assert len(recorder.installed) == 1
    scheduler.close()
    assert not process.is_alive() and process.exitcode == 0


class _FailingSm:
    """A robot model whose Sm cannot be computed (as a singular posture would)."""

    def __init__(self, robot) -> None:
        self._robot = robot

    def __getattr__(self, name: str):
        return getattr(self._robot, name)

    def sm(self, link_angle_rad, contact):
        raise np.linalg.LinAlgError("singular posture")


def test_a_failed_design_is_raised_on_the_loops_thread_as_it_was() -> None:
    config = load_config(robot="dyros-jet")
    scheduler, _ = _scheduler(_FailingSm(robot_model(config)))
    try:
        with pytest.raises(np.linalg.LinAlgError, match="singular posture"):
            for tick in range(scheduler.lead_ticks + 1):
                scheduler.update(tick, READY, LqrContact.BOTH_FEET, LqrContact.BOTH_FEET)
    finally:
        scheduler.close()


def test_a_designer_process_that_died_is_an_error_not_a_hang() -> None:
    scheduler, _ = _scheduler()
    process = scheduler._worker._process  # type: ignore[attr-defined]
    try:
        process.kill()
        process.join()
        with pytest.raises(GainDesignerLost, match="process ended"):
            for tick in range(scheduler.lead_ticks + 1):
                scheduler.update(tick, READY, LqrContact.BOTH_FEET, LqrContact.BOTH_FEET)
    finally:
        scheduler.close()


def _process_state(pid: int) -> str:
    """The process's state letter from /proc (T: stopped)."""
    with open(f"/proc/{pid}/stat") as stat:
        return stat.read().rsplit(")", 1)[1].split()[0]


def _stopped_soon(pid: int) -> bool:
    """Whether the process is stopped within 0.5 s (a signal acts asynchronously)."""
    deadline = time.monotonic() + 0.5
    while _process_state(pid) != "T":
        if time.monotonic() > deadline:
            return False
        time.sleep(0.005)
    return True


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc")
@pytest.mark.parametrize("wall_clock", [False, True], ids=["lockstep", "wall-clock"])
def test_a_design_waits_while_the_wall_clock_loop_is_in_its_tick(wall_clock: bool) -> None:
    """On the wall clock a design in progress is stopped while the loop is in its tick (bus
    read, compute, write) and goes on while the loop sleeps (it never runs beside the tick); in
    lock-step it is never stopped. The design still arrives, and a scheduler closed mid-tick
    ends its designer."""
    scheduler, recorder = _scheduler(wall_clock=wall_clock)
    process = scheduler._worker._process  # type: ignore[attr-defined]
    scheduler.update(0, READY, LqrContact.BOTH_FEET, LqrContact.BOTH_FEET)
    assert scheduler._pending is not None  # type: ignore[attr-defined]
    scheduler.tick_active(True)
    assert _stopped_soon(process.pid) is wall_clock
    scheduler.tick_active(False)
    time.sleep(0.05)
    assert _process_state(process.pid) != "T"
    tick, deadline = 1, time.monotonic() + 20.0
    while not recorder.installed and time.monotonic() < deadline:
        scheduler.tick_active(True)
        scheduler.tick_active(False)
        scheduler.update(tick, READY, LqrContact.BOTH_FEET, LqrContact.BOTH_FEET)
        tick += 1
        time.sleep(0.005)
    assert recorder.installed
    scheduler.tick_active(True)
    scheduler.update(tick, READY, LqrContact.LEFT_FOOT, LqrContact.LEFT_FOOT)  # mid-tick
    assert _stopped_soon(process.pid) is wall_clock  # it starts when the tick is over
    scheduler.close()  # mid-tick: the stopped designer is continued, told to leave, and ends
    assert not process.is_alive() and process.exitcode == 0
