"""The paper's Fig. 5 case on the emulated testbed: the actuator's own position control ("pid")
pushing the link into the block trips the actuator's overload protection; the stack sees it on
the first read after it, stops commanding, reports it, and keeps the whole story in the log.
The DOB controller in the same experiment does not trip; with the software current guard on,
pid does not trip either."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.dynamixel import HardwareError
from drivers.joint_bus import ActuatorFault
from tests.support.rig import (
    DXL_ID,
    assert_log_complete,
    config_with,
    emulated_testbed,
    first_tick,
    read_device,
    run_on,
)

DURATION_S = 5.0  # contact at ~2.3 s; pid trips ~1.8 s later


@pytest.fixture(scope="module")
def pid_unguarded(tmp_path_factory: pytest.TempPathFactory):
    config = config_with(current_guard=False)
    out = tmp_path_factory.mktemp("fig5") / "pid"
    with emulated_testbed(config, "contact") as emulator:
        result, run = run_on(emulator, config, "contact", "pid", out, duration_s=DURATION_S)
        device = read_device(emulator.endpoints)
    return result, run, device


@pytest.mark.timeout(120)
def test_pid_into_the_block_trips_the_overload_and_the_stack_sees_it_at_once(
    pid_unguarded,
) -> None:
    result, run, device = pid_unguarded
    columns = run.columns
    faults = columns["actuator_fault"].astype(int)
    trip = first_tick(faults != 0)
    assert trip is not None, "the actuator's overload protection did not trip"
    assert faults[trip] == ActuatorFault.OVERLOAD
    # Within one tick: the read before showed a healthy device with torque on.
    assert faults[trip - 1] == 0 and columns["torque_enabled"][trip - 1] == 1
    event = run.first_trip()
    assert event is not None
    assert (event["cause"], event["joint"], event["action"]) == (
        "hardware_error",
        "testbed",
        "torque_off",
    )
    assert event["tick"] == trip and event["time_s"] == pytest.approx(trip * 0.005)
    assert "OVERLOAD" in event["message"] and f"actuator {DXL_ID}" in event["message"]
    assert result.ending.text == "safety stop: hardware_error (torque_off)"
    # It stops commanding on that tick: no goal is sent any more, the state stays latched.
    assert np.isnan(columns["goal_rad"][trip:]).all()
    assert np.isfinite(columns["goal_rad"][:trip]).all()
    assert set(columns["supervisor_state"][trip:]) == {"torque_off"}
    assert run.events_of("torque_off")[0]["time_s"] == pytest.approx(trip * 0.005)
    # The device says the same (read with ROBOTIS's SDK after the run): shut down, torque off.
    assert device.hardware_error == HardwareError.OVERLOAD
    assert device.torque_enabled == 0


@pytest.mark.timeout(120)
def test_the_log_holds_the_whole_story_of_the_trip(pid_unguarded) -> None:
    result, run, _ = pid_unguarded
    assert_log_complete(run)
    columns = run.columns
    force = columns["contact_force_n"]
    trip = first_tick(columns["actuator_fault"] != 0)
    contact = first_tick(force > 1.0)
    assert contact is not None and trip is not None and contact < trip
    # The paper: the position-controlled joint reaches >= 70 N before its protection acts
    assert force[contact:trip].max() >= 70.0
    # after the trip the servo is off and the link rests on the block: the force falls
    assert force[-1] < 0.5 * force[contact:trip].max()
    assert len(columns["time_s"]) == round(DURATION_S / 0.005) + 5  # every tick, stop cycles
    metrics = run.summary["metrics"]
    assert metrics["overload_tripped"] is True
    assert metrics["trip_time_after_contact_s"] > 1.0
    assert result.ticks == run.summary["ticks"]


@pytest.mark.timeout(120)
def test_the_dob_controller_in_the_same_experiment_does_not_trip(tmp_path) -> None:
    config = config_with(current_guard=False)
    with emulated_testbed(config, "contact") as emulator:
        _, run = run_on(
            emulator, config, "contact", "gc+lqr+dob", tmp_path / "dob", duration_s=DURATION_S
        )
        device = read_device(emulator.endpoints)
    assert run.termination == "completed"
    assert (run.columns["actuator_fault"] == 0).all()
    assert run.trips() == []
    force = run.columns["contact_force_n"]
    assert 10.0 < force.max() < 50.0  # the paper: compliant at 20-40 N
    assert device.hardware_error == 0 and device.torque_enabled == 0  # exit: torque off


@pytest.mark.timeout(120)
def test_with_the_software_guard_pid_backs_off_before_the_actuator_trips(
    tmp_path, pid_unguarded
) -> None:
    _, unguarded, _ = pid_unguarded
    tripped_at = first_tick(unguarded.columns["actuator_fault"] != 0)
    config = config_with(current_guard=True)
    with emulated_testbed(config, "contact") as emulator:
        _, run = run_on(emulator, config, "contact", "pid", tmp_path / "pid", duration_s=DURATION_S)
        device = read_device(emulator.endpoints)
    assert (run.columns["actuator_fault"] == 0).all(), "the actuator tripped despite the guard"
    assert device.hardware_error == 0
    event = run.first_trip()
    assert event is not None and (event["cause"], event["action"]) == ("current", "back_off")
    assert run.termination == "safety stop: current (back_off)"
    assert event["tick"] < tripped_at
    # backed off: the goal moved away from the block (up) and the contact force collapsed
    goal = run.columns["goal_rad"]
    assert goal[event["tick"]] > goal[event["tick"] - 1] + 0.04
    half_second_later = event["tick"] + 100
    assert (run.columns["contact_force_n"][half_second_later:] < 5.0).all()
    assert run.events_of("link_stale") == []  # a blocked link is not a stale encoder
