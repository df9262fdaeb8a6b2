"""The Python API (hil/api.py): your own loop through the supervisor, on the same spine as
`hil run`; torque off and the record complete on every exit path; `Robot.run` is `hil run`."""

from __future__ import annotations

import doctest
import json
import os
import signal
from pathlib import Path

import numpy as np
import pytest

import hil
import hil.api
from drivers.joint_bus import BusError
from tests.support.rig import assert_log_complete, load_run


def _robot(tmp_path: Path, setup: hil.Setup = hil.Setup.IN_PROCESS) -> hil.Robot:
    return hil.open_robot(robot="testbed", setup=setup, out_root=tmp_path)


def _events(run_dir: Path) -> list[dict]:
    return [json.loads(line) for line in (run_dir / "events.jsonl").read_text().splitlines()]


def test_the_public_surface_is_at_the_top_level() -> None:
    for name in hil.__all__:
        assert getattr(hil, name) is not None, name
    assert hil.open_robot is hil.api.open_robot and hil.Controller.__module__.startswith("hil.")


def test_a_loop_of_your_own_is_recorded_like_a_run(tmp_path: Path) -> None:
    with _robot(tmp_path).loop("hold", duration_s=0.5) as loop:
        for sample in loop:
            assert sample.motor_angle_rad.shape == (1,)
            loop.cycle_actuation(sample.motor_angle_rad + 0.01)
    result = loop.result
    assert result is not None and result.exit_status == 0 and result.ticks == 110
    run = load_run(result.out_dir)
    assert_log_complete(run)
    phases = list(run.columns["phase"])
    assert phases[:5] == ["hold"] * 5 and phases[-5:] == ["stop"] * 5
    assert phases.count("experiment") == 100
    goal = run.columns["goal_rad"][5:105]
    motor = run.columns["motor_angle_rad"][5:105]
    assert np.all(goal > motor[0])  # your goals, through the supervisor
    assert run.summary["exit"] == ["torque off"] and run.summary["termination"] == "completed"


def test_an_exception_in_your_loop_turns_torque_off_and_is_raised(tmp_path: Path) -> None:
    with pytest.raises(ZeroDivisionError), _robot(tmp_path).loop("bug") as loop:
        for sample in loop:
            if loop.time_s > 0.2:
                raise ZeroDivisionError("a bug in your loop")
            loop.cycle_actuation(sample.motor_angle_rad)
    result = loop.result
    assert result is not None and result.exit_status == 1
    assert result.ending.text == "error: ZeroDivisionError: a bug in your loop"
    events = _events(result.out_dir)
    assert [e["kind"] for e in events][-2:] == ["error", "torque_off"]
    assert_log_complete(load_run(result.out_dir))


def test_ctrl_c_ends_your_loop_as_interrupted(tmp_path: Path) -> None:
    with _robot(tmp_path).loop("interrupted") as loop:
        for sample in loop:
            if loop.time_s == pytest.approx(0.1):
                os.kill(os.getpid(), signal.SIGINT)  # what Ctrl-C sends
            loop.cycle_actuation(sample.motor_angle_rad)
    result = loop.result
    assert result is not None and result.ending.text == "interrupted: SIGINT"
    assert result.exit_status == 1 and result.exit_notes == ("torque off",)
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # given back


def test_a_lost_bus_ends_your_loop_as_a_bus_failure(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    with _robot(tmp_path).loop("unplugged") as loop:
        bus = loop._running_spine.bus
        real_read = bus.read

        def read() -> object:
            if loop.time_s > 0.2:
                raise BusError("the port vanished (injected by the test)")
            return real_read()

        monkeypatch.setattr(bus, "read", read)
        monkeypatch.setattr(bus, "finish_read", read)
        for sample in loop:
            loop.cycle_actuation(sample.motor_angle_rad)
    result = loop.result
    assert result is not None and result.ending.text.startswith("bus failure: the port vanished")
    assert_log_complete(load_run(result.out_dir))


def test_the_supervisor_stands_in_front_of_your_goals(tmp_path: Path) -> None:
    """A goal that runs away is limited in rate and then held by the supervisor: the run is a
    safety stop, and what reached the actuator never moved faster than [safety] allows."""
    robot = _robot(tmp_path)
    limit = robot.config.safety.max_goal_rate_rad_s
    with robot.loop("runaway", duration_s=2.0) as loop:
        for sample in loop:
            loop.cycle_actuation(sample.motor_angle_rad + 1.0)  # 1 rad ahead, every tick
    run = load_run(loop.result.out_dir)
    goal = run.columns["goal_rad"]
    running = run.columns["supervisor_state"] == "run"
    steps = np.abs(np.diff(goal))[running[1:] & running[:-1]]
    assert steps.size > 50 and np.max(steps) <= limit * 0.005 * (1 + 1e-6)
    held = ~running & (run.columns["phase"] == "experiment")
    assert held.sum() > 10 and np.ptp(goal[held][1:]) == 0  # then held where it was
    assert loop.result.ending.termination.value == "safety stop"


def test_a_second_actuation_in_one_cycle_is_refused(tmp_path: Path) -> None:
    with _robot(tmp_path).loop("twice", duration_s=0.1) as loop:
        sample = loop.begin_cycle()
        loop.cycle_actuation(sample.motor_angle_rad)
        with pytest.raises(RuntimeError, match="twice"):
            loop.cycle_actuation(sample.motor_angle_rad)
        loop.end_cycle()


def test_robot_run_is_hil_run(tmp_path: Path) -> None:
    result = _robot(tmp_path).run("impact", "examples/pd_gravity.py:PdGravity", duration_s=1.0)
    assert result.exit_status == 0 and result.out_dir.name.endswith("impact-pd-gravity")
    with pytest.raises(hil.ConfigError, match="unknown controller"):
        _robot(tmp_path).run("impact", "lqg")


def test_the_api_docstrings_examples_run(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    failures, tried = doctest.testmod(hil.api, optionflags=doctest.ELLIPSIS)
    assert tried >= 5 and failures == 0
