"""The exit path's torque off is tried again as on hardware (issue 25): one try that the bus did
not take (a lost status packet on a loaded machine) printed TORQUE COULD NOT BE TURNED OFF and
exit 3 on a healthy emulator. Now it is tried up to EXIT_TORQUE_OFF_TRIES times, and the record
says how many it took."""

from __future__ import annotations

from pathlib import Path

import pytest

from drivers.joint_bus import BusError
from hil.config import load_config
from hil.loop.torque import EXIT_TORQUE_OFF_TRIES
from hil.robots import get_experiment
from hil.wiring.in_process import in_process_bus
from tests.support.rig import assert_log_complete, run_in_process

CONFIG = load_config()


def _bus_whose_torque_off_fails(times: int, monkeypatch: pytest.MonkeyPatch):
    bus = in_process_bus(CONFIG, get_experiment("impact"), ())
    real_disable = bus.disable
    calls = []

    def disable() -> None:
        calls.append(1)
        if len(calls) <= times:
            raise BusError("no status packet (injected by the test)")
        real_disable()

    monkeypatch.setattr(bus, "disable", disable)
    return bus, calls


def test_a_torque_off_the_bus_did_not_take_at_once_is_tried_again(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    bus, calls = _bus_whose_torque_off_fails(1, monkeypatch)
    result, run = run_in_process(CONFIG, "impact", "pid", tmp_path, duration_s=0.5, bus=bus)
    assert run.termination == "completed"
    assert not result.torque_off_failed
    assert run.summary["exit"][0] == "torque off (2 tries)"
    (event,) = run.events_of("torque_off")
    assert event["tries"] == 2 and event["message"] == "exit: torque off (2 tries)"
    assert not run.events_of("torque_off_failed")
    assert len(calls) == 2
    assert bus.testbed is not None and not bus.testbed.robot.devices[0].torque_enabled
    assert_log_complete(run)


def test_a_torque_off_that_never_takes_is_reported_after_its_tries(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    bus, calls = _bus_whose_torque_off_fails(100, monkeypatch)
    result, run = run_in_process(CONFIG, "impact", "pid", tmp_path, duration_s=0.5, bus=bus)
    assert result.torque_off_failed
    assert (
        run.summary["exit"][0]
        == f"torque off FAILED ({EXIT_TORQUE_OFF_TRIES} tries; see events.jsonl)"
    )
    (event,) = run.events_of("torque_off_failed")
    assert event["tries"] == EXIT_TORQUE_OFF_TRIES
    assert len(calls) == EXIT_TORQUE_OFF_TRIES


def test_a_torque_off_taken_at_once_says_one_try(tmp_path: Path) -> None:
    _, run = run_in_process(CONFIG, "impact", "pid", tmp_path, duration_s=0.5)
    assert run.summary["exit"][0] == "torque off"
    (event,) = run.events_of("torque_off")
    assert event["tries"] == 1 and event["message"] == "exit: torque off"
