"""Every exit path leaves the actuators in the configured torque state and a complete log on
disk: the normal end, on_exit = hold, an exception in the controller, a lost bus, an actuator
that goes silent - the loop of `hil run` on the in-process joint bus, whose emulated devices are
inspected afterwards. Signals and a killed emulator process are in tests/e2e/."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import hil.loop.runner
import hil.loop.torque
from drivers.joint_bus import BusError, JointSample
from hil.config import load_config
from hil.experiments import CONTACT, IMPACT
from hil.wiring.in_process import InProcessJointBus, in_process_bus
from sim_backend.dynamixel.device import H54Device
from sim_backend.scenario import parse_fault
from tests.support.rig import (
    PERIOD_S,
    assert_log_complete,
    config_with,
    run_in_process,
)

CONFIG = load_config()


def _device(bus: InProcessJointBus, joint: int = 0) -> H54Device:
    assert bus.testbed is not None
    return bus.testbed.robot.devices[joint]


def test_normal_end_leaves_torque_off(tmp_path: Path) -> None:
    bus = in_process_bus(CONFIG, IMPACT)
    result, run = run_in_process(CONFIG, IMPACT, "gc+lqr+dob", tmp_path, duration_s=1.5, bus=bus)
    assert result.ok and run.termination == "completed"
    assert_log_complete(run)
    assert run.summary["exit"][0] == "torque off"
    assert not _device(bus).torque_enabled and _device(bus).hardware_error_status == 0


def test_on_exit_hold_leaves_torque_on_holding_the_last_goal(tmp_path: Path) -> None:
    config = config_with(on_exit="hold")
    bus = in_process_bus(config, IMPACT)
    result, run = run_in_process(config, IMPACT, "pid", tmp_path, duration_s=0.5, bus=bus)
    assert result.ok
    assert_log_complete(run)
    assert run.summary["exit"][0] == "torque left on (on_exit = hold)"
    assert _device(bus).torque_enabled


class _FailingController:
    """The run's real controller, with a bug that fires at its `fail_at`-th step."""

    def __init__(self, inner: object, fail_at: int) -> None:
        self._inner = inner
        self._fail_at = fail_at
        self._steps = 0

    def __getattr__(self, name: str) -> object:
        return getattr(self._inner, name)

    def step(self, state: object) -> np.ndarray:
        self._steps += 1
        if self._steps == self._fail_at:
            raise ZeroDivisionError("a controller bug (injected by the test)")
        return self._inner.step(state)


def test_an_exception_in_the_controller_leaves_torque_off_and_the_log_complete(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The controller's fault, not the run's: the supervisor's controller_fault turns torque off
    on the next tick, the run goes on to its end with torque off (a safety stop), and the
    traceback is in events.jsonl."""
    real_build = hil.loop.runner.build
    monkeypatch.setattr(
        hil.loop.runner,
        "build",
        lambda *args: _FailingController(real_build(*args), fail_at=100),
    )
    bus = in_process_bus(CONFIG, CONTACT)
    result, run = run_in_process(CONFIG, CONTACT, "gc+lqr+dob", tmp_path, duration_s=2.0, bus=bus)
    assert run.termination == "safety stop: controller_fault (torque_off)"
    assert_log_complete(run)
    (fault,) = run.events_of("controller_fault")
    assert fault["tick"] == 5 + 99  # stop cycles, then 99 good steps
    (trace,) = run.events_of("controller_traceback")
    assert "ZeroDivisionError: a controller bug" in trace["message"]
    torque_off = run.events_of("torque_off")[0]
    assert torque_off["time_s"] == pytest.approx(fault["time_s"] + PERIOD_S)
    assert run.columns["torque_enabled"][fault["tick"] + 2] == 0
    assert run.summary["exit"][0] == "torque off" and not _device(bus).torque_enabled


def test_a_lost_bus_ends_the_run_with_a_complete_log_and_says_torque_could_not_be_set(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    bus = in_process_bus(CONFIG, CONTACT)
    real_read = bus.read

    def read_until_unplugged() -> JointSample:
        if bus.reads >= 200:
            raise BusError("the port vanished (injected by the test)")
        return real_read()

    def no_disable() -> None:
        raise BusError("the port vanished (injected by the test)")

    monkeypatch.setattr(bus, "read", read_until_unplugged)
    monkeypatch.setattr(bus, "disable", no_disable)
    result, run = run_in_process(CONFIG, CONTACT, "gc+lqr+dob", tmp_path, duration_s=3.0, bus=bus)
    assert run.termination.startswith("bus failure: the port vanished")
    assert not result.termination.ran_its_course
    assert_log_complete(run)
    assert run.summary["ticks"] == 200
    assert run.events_of("bus_failure")
    assert "torque off FAILED" in run.summary["exit"][0]


def test_torque_off_reaches_an_actuator_that_was_silent_as_soon_as_it_answers(
    tmp_path: Path,
) -> None:
    fault = parse_fault("silent_id@1.0+0.1")  # 20 ticks; the next planned retry would be later
    bus = in_process_bus(CONFIG, CONTACT, (fault,))
    result, run = run_in_process(CONFIG, CONTACT, "pid", tmp_path, duration_s=1.3, bus=bus)
    assert run.termination == "safety stop: bus_error (torque_off)"
    assert_log_complete(run)
    (back,) = run.notices("bus_recovered")
    torque_off = run.events_of("torque_off")[0]
    assert torque_off["time_s"] == pytest.approx(back["time_s"])  # on the tick it answered
    assert run.events_of("torque_off_failed")  # tried while it was silent
    assert run.columns["torque_enabled"][back["tick"] + 1] == 0
    assert not _device(bus).torque_enabled


def test_a_permanently_silent_actuator_is_reported_as_unreachable(tmp_path: Path) -> None:
    """After the bus_error stop the loop keeps reading, tries torque off only every
    DISABLE_RETRY_TICKS ticks, and the exit path says honestly that torque could not be set:
    the device never heard it and holds its last goal with torque on."""
    bus = in_process_bus(CONFIG, CONTACT, (parse_fault("silent_id@1.0"),))
    _, run = run_in_process(CONFIG, CONTACT, "pid", tmp_path, duration_s=1.5, bus=bus)
    assert run.termination == "safety stop: bus_error (torque_off)"
    assert "torque off FAILED" in run.summary["exit"][0]
    assert_log_complete(run)
    assert len(run.events_of("torque_off_failed")) == 2  # the first try (retries quiet) + exit
    assert _device(bus).torque_enabled  # it never heard the torque off
    silent_ticks = run.summary["ticks"] - round(1.0 / PERIOD_S)
    assert silent_ticks > 3 * hil.loop.torque.DISABLE_RETRY_TICKS
