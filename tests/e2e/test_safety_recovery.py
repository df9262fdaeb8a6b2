"""Recovery is explicit: after the actuator's protection tripped, a run is refused until the
device is rebooted (`hil reboot`, or `hil run --reboot-first`), and the run that follows re-homes
slowly from where the link lies to the experiment's start.

To keep the suite fast the emulated actuator's overload protection is set to trip after 0.3 s
(the [emulator] servo override users have), so pid trips ~0.6 s after contact.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from drivers.dynamixel import HardwareError
from hil.cli import main
from hil.config import Config
from hil.loop.homing import REHOME_RATE_RAD_S
from tests.support.rig import (
    PERIOD_S,
    assert_log_complete,
    config_with,
    emulated_testbed,
    read_device,
    run_on,
)


def _quick_trip_config() -> Config:
    config = config_with(current_guard=False)
    return config.changed("emulator", servo={"overload_trip_time_s": 0.3})


def _trip(emulator, config: Config, out: Path) -> None:
    result, _ = run_on(emulator, config, "contact", "pid", out, duration_s=3.2)
    assert result.ending.text == "safety stop: hardware_error (torque_off)"
    device = read_device(emulator.endpoints)
    assert device.hardware_error == HardwareError.OVERLOAD and device.torque_enabled == 0


@pytest.mark.timeout(120)
def test_after_a_trip_a_run_is_refused_until_reboot_first_then_it_rehomes_slowly(
    tmp_path: Path,
) -> None:
    config = _quick_trip_config()
    with emulated_testbed(config, "contact") as emulator:
        _trip(emulator, config, tmp_path / "trip")
        refused, _ = run_on(
            emulator, config, "contact", "gc+lqr+dob", tmp_path / "refused", duration_s=1.0
        )
        assert refused.ending.text.startswith(
            "start refused: actuator 1 (testbed) reports OVERLOAD"
        )
        assert "--reboot-first" in refused.ending.text
        device = read_device(emulator.endpoints)
        assert device.hardware_error == HardwareError.OVERLOAD  # nothing cleared it
        assert device.torque_enabled == 0
        result, run = run_on(
            emulator,
            config,
            "contact",
            "gc+lqr+dob",
            tmp_path / "recovered",
            duration_s=1.5,
            reboot_first=True,
        )
        device = read_device(emulator.endpoints)
    assert result.ok
    assert_log_complete(run)
    kinds = [e["kind"] for e in run.events]
    assert kinds[:5] == ["open", "reboot", "reboot", "torque_on", "homing"]
    assert (run.columns["actuator_fault"] == 0).all() and device.hardware_error == 0
    homing = run.summary["homing"]
    start, target = homing["start_rad"][0], homing["target_rad"][0]
    assert start < -0.15 and target == 0.0  # from the block back to the experiment's start
    reference = run.columns["reference_rad"]
    link = run.columns["link_angle_rad"]
    homing_ticks = round(homing["duration_s"] / PERIOD_S + 0.5)
    stop_cycles = 5
    end = stop_cycles + homing_ticks
    # the actuator's own servo follows the ramp: neither reference nor goal moves faster
    goal = run.columns["goal_rad"]
    rate_step = REHOME_RATE_RAD_S * PERIOD_S + 1e-9
    assert np.abs(np.diff(reference[:end])).max() <= rate_step
    assert np.abs(np.diff(goal[stop_cycles:end])).max() <= rate_step
    assert reference[0] == pytest.approx(link[0])  # starts where the link is
    # arrived before the experiment's timeline begins, short by the gravity sag through the
    # gear and the servo (6.2 N m / 2000 + 6.2 N m / 785 N m/rad = 0.011 rad)
    assert -0.02 < link[end] - target < 0.0
    assert (run.columns["uc_rad"][:end] == 0).all()  # the controller starts after it
    # then the experiment runs as usual (its clock starts at the stop cycles' end, as without
    # homing): its reference holds until 1 s, then ramps down; the run is longer by the homing
    assert np.all(reference[end : end + 190] == 0.0) and reference[-1] < 0.0
    assert len(reference) == homing_ticks + round(1.5 / PERIOD_S) + stop_cycles


@pytest.mark.timeout(120)
def test_hil_reboot_clears_the_latched_error_and_leaves_torque_off(tmp_path: Path, capsys) -> None:
    config = _quick_trip_config()
    with emulated_testbed(config, "contact") as emulator:
        _trip(emulator, config, tmp_path / "trip")
        code = main(["reboot", "--attach", json.dumps(emulator.endpoints), "--json"])
        device = read_device(emulator.endpoints)
    assert code == 0
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1]) == {
        "rebooted": {"1": "none"}
    }
    assert device.hardware_error == 0 and device.torque_enabled == 0
