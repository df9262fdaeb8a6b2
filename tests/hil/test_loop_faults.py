"""Each injected fault leads to its documented reaction (docs/safety.md) within a bounded number
of ticks: the loop of `hil run` on the in-process joint bus, with the emulator's own fault
schedule (lock-step, so the tick counts are exact and repeatable). The same faults through the
real buses and `hil run --inject` are in tests/e2e/test_safety_faults.py.

The controller is gc+lqr+dob; the contact experiment holds until 1 s, then ramps the reference
down (the motor moves), so faults injected at 1.0-1.5 s hit a moving joint. Ticks are counted
from the first tick that sees the fault to the tick on which the safe state is applied, both
included.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from drivers.joint_bus import JointSample
from hil.cli.common import parse_injections
from hil.config import load_config
from tests.support.rig import PERIOD_S, assert_log_complete, run_in_process

CONFIG = load_config()
SAFETY = CONFIG.safety


@dataclass(frozen=True)
class FaultCase:
    inject: str
    duration_s: float
    cause: str | None  # None: tolerated (recorded as a notice, no safe state)
    action: str | None
    max_ticks: int  # the documented bound (ticks that see the fault, reaction tick included)
    notice: str | None = None


CASES = (
    FaultCase("dropped_reply@1.0", 1.3, None, None, 1, notice="bus_glitch"),
    FaultCase("corrupt_crc@1.0", 1.3, None, None, 1, notice="bus_glitch"),
    FaultCase("dropped_reply@1.0+0.05", 1.3, "bus_error", "torque_off", SAFETY.bus_error_ticks),
    FaultCase("corrupt_crc@1.0+0.05", 1.3, "bus_error", "torque_off", SAFETY.bus_error_ticks),
    FaultCase("silent_id@1.0", 1.2, "bus_error", "torque_off", SAFETY.bus_error_ticks),
    FaultCase("dead_encoder@1.0", 1.2, "link_stale", "hold", SAFETY.link_stale_ticks),
    # frozen while the motor moves: fires once the motor moved half the deflection bound
    # (0.03 rad) - at the ramp's ~0.17 rad/s there, 0.03 / 0.17 / 0.005 = 35 ticks at most
    FaultCase("stale_encoder@1.5", 1.8, "link_stale", "hold", 40),
    FaultCase("noisy_encoder@1.0", 1.3, "link_noisy", "hold", 20),
    FaultCase("overrun@1.0+0.2", 1.3, "overrun", "hold", SAFETY.overrun_limit + 1),
)


def _start_s(case: FaultCase) -> float:
    return float(case.inject.partition("@")[2].partition("+")[0])


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.inject)
def test_an_injected_fault_gets_its_documented_reaction_in_bounded_ticks(
    case: FaultCase, tmp_path: Path
) -> None:
    faults, overruns = parse_injections([case.inject])
    result, run = run_in_process(
        CONFIG,
        "contact",
        "gc+lqr+dob",
        tmp_path,
        duration_s=case.duration_s,
        faults=faults,
        overruns=overruns,
    )
    assert_log_complete(run)
    fault_tick = round(_start_s(case) / PERIOD_S)
    state = run.columns["supervisor_state"]
    if case.cause is None:
        assert run.termination == "completed" and result.ok
        assert run.trips() == [] and set(state) == {"run"}
        (notice,) = run.notices(case.notice)
        assert notice["tick"] == fault_tick + 1  # the device answered again on the next tick
        assert run.summary["safety_counters"]["motor_invalid_ticks"] == {"testbed": 1}
        return
    event = run.first_trip()
    assert event is not None, f"{case.inject}: no reaction"
    assert (event["cause"], event["action"]) == (case.cause, case.action)
    assert run.termination == f"safety stop: {case.cause} ({case.action})"
    ticks = event["tick"] - fault_tick + 1
    assert 1 <= ticks <= case.max_ticks
    assert state[event["tick"] - 1] == "run"
    assert set(state[event["tick"] :]) == {case.action}
    goal = run.columns["goal_rad"][event["tick"] :]
    if case.action == "torque_off":
        assert np.isnan(goal).all()  # nothing commanded any more
    else:
        assert np.ptp(goal) == 0.0  # one goal held to the end


def test_every_injected_fault_fired(tmp_path: Path) -> None:
    """A fault that never took effect would make the case above pass vacuously."""
    faults, _ = parse_injections(["silent_id@0.5+0.01", "noisy_encoder@0.6+0.05"])
    from hil.experiments import CONTACT
    from hil.wiring.in_process import in_process_bus

    bus = in_process_bus(CONFIG, CONTACT, faults)
    run_in_process(CONFIG, CONTACT, "pid", tmp_path, duration_s=0.8, bus=bus)
    assert bus.testbed is not None and bus.testbed.schedule.fired == [1, 1]


def test_an_actuator_fault_with_torque_still_on_stops_the_run(tmp_path: Path) -> None:
    """The emulated H54 reports overheating (not in its Shutdown mask: it keeps torque on) in
    the middle of a run: the loop's supervisor turns torque off itself on that tick."""
    from hil.experiments import IMPACT
    from hil.wiring.in_process import in_process_bus

    bus = in_process_bus(CONFIG, IMPACT)
    real_read = bus.read

    def read_and_overheat() -> JointSample:
        if bus.reads == 300:
            bus.testbed.robot.devices[0].raise_hardware_error(0x04)  # OVERHEATING
        return real_read()

    bus.read = read_and_overheat  # type: ignore[method-assign]
    result, run = run_in_process(CONFIG, IMPACT, "gc+lqr+dob", tmp_path, duration_s=2.0, bus=bus)
    event = run.first_trip()
    assert event["cause"] == "hardware_error" and event["tick"] == 300
    assert "torque is on" in event["message"]
    assert run.columns["torque_enabled"][300] == 1  # the device had not turned itself off
    assert not bus.testbed.robot.devices[0].torque_enabled  # the loop did
