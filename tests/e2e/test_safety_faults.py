"""Injected faults through the real buses, rehearsed exactly as a user would: `hil run contact
--inject FAULT@T[+D]` on the embedded emulated testbed (lock-step, so the tick counts are exact
and repeatable). The in-process bus runs every case in milliseconds
(tests/hil/test_loop_faults.py); here the ones whose path through the wire differs: a lost reply
and a corrupt one (the driver's CRC check), a silent ID (the driver's timeout), a dead encoder
(the CAN reader's missing TPDO) and a noisy one.

The controller is gc+lqr+dob; the contact experiment holds until 1 s, then ramps the reference
down (the motor moves), so faults injected at 1.0-1.5 s hit a moving joint.

`pytest tests/e2e/test_safety_faults.py -s` prints the measured fault -> reaction -> ticks table.
Ticks are counted from the first tick that sees the fault (the emulator applies a fault from
the first CAN SYNC at or after its start time) to the tick on which the safe state is applied,
both included; "wall" is the loop's own time over those ticks (timing.csv): in lock-step
emulation the driver's timeouts are widened to 50 ms latency on purpose (hil/hardware.py), so a
silent device costs ~0.1 s of wall time per tick here and ~4.3 ms on hardware settings.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from hil.bench.soak import NOISE_DETECTION_WINDOWS
from hil.cli.exit_codes import ExitCode
from hil.config import load_config
from tests.support.rig import PERIOD_S, Run, assert_log_complete, hil_run

SAFETY = load_config().safety


@dataclass(frozen=True)
class FaultCase:
    inject: str
    duration_s: float  # of the run: short, a silent device costs its timeout every tick
    cause: str | None  # None: tolerated (recorded as a notice, no safe state)
    action: str | None
    max_ticks: int  # the documented bound (ticks that see the fault, reaction tick included)
    notice: str | None = None
    torque_left_on: bool = False  # the device cannot hear the torque off: `hil run` exits 3


CASES = (
    FaultCase("dropped_reply@1.0", 1.3, None, None, 1, notice="bus_glitch"),
    FaultCase("corrupt_crc@1.0+0.05", 1.3, "bus_error", "torque_off", SAFETY.bus_error_ticks),
    FaultCase(
        "silent_id@1.0",
        1.05,
        "bus_error",
        "torque_off",
        SAFETY.bus_error_ticks,
        torque_left_on=True,
    ),  # fmt: skip
    FaultCase("dead_encoder@1.0", 1.03, "link_stale", "hold", SAFETY.link_stale_ticks),
    # a random delay: three windows (docs/safety.md, "Noise vs. motion"); this seed's is 16
    FaultCase(
        "noisy_encoder@1.0",
        1.3,
        "link_noisy",
        "hold",
        NOISE_DETECTION_WINDOWS * SAFETY.link_noise_window_ticks,
    ),  # fmt: skip
)


def _start_s(case: FaultCase) -> float:
    return float(case.inject.partition("@")[2].partition("+")[0])


def _wall_s(run: Run, first: int, last: int) -> float:
    with open(run.dir / "timing.csv") as f:
        rows = list(csv.DictReader(f))
    return sum(float(r["cycle_s"]) for r in rows[first : last + 1])


@pytest.mark.timeout(120)
@pytest.mark.parametrize("case", CASES, ids=lambda c: c.inject)
def test_an_injected_fault_gets_its_documented_reaction_in_bounded_ticks(
    case: FaultCase, tmp_path: Path
) -> None:
    run = hil_run(
        tmp_path,
        "contact",
        "--controller",
        "gc+lqr+dob",
        "--duration",
        str(case.duration_s),
        "--inject",
        case.inject,
    )
    assert_log_complete(run)
    fault_tick = round(_start_s(case) / PERIOD_S)
    state = run.columns["supervisor_state"]
    if case.cause is None:
        assert run.exit_code == 0 and run.termination == "completed"
        assert run.trips() == [] and set(state) == {"run"}
        (notice,) = run.notices(case.notice)
        assert notice["tick"] == fault_tick + 1  # the device answered again on the next tick
        assert run.summary["safety_counters"]["motor_invalid_ticks"] == {"testbed": 1}
        ticks = 1
        reaction = f"tolerated, {case.notice} notice"
    else:
        assert run.exit_code == (ExitCode.TORQUE_NOT_OFF if case.torque_left_on else 1)
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
        reaction = f"{case.cause} -> {case.action}"
    wall_ms = 1000 * _wall_s(run, fault_tick, fault_tick + ticks - 1)
    print(f"\n| {case.inject} | {reaction} | {ticks} | {wall_ms:.0f} ms | {run.summary['exit']} |")
