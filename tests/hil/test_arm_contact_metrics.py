"""The arm's contact experiment (hil/experiments/arm_contact.py) on a made-up log whose figures
are known by construction: contact time, peak and mean force with torque on, the overload trip
of any joint and its time after contact, the force's drift; and its predictions, where a safety
stop of pid is a protection acting (a result), not a run that is missing."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from drivers.joint_bus import ActuatorFault
from hil.experiments.arm import JointMove
from hil.experiments.arm_contact import ArmContactExperiment, arm_contact_relations
from hil.experiments.base import Block, World
from hil.output.records import RunEntry, RunResult
from hil.output.rundir import RunData
from hil.vocabulary import ControllerChoice, ControllerKind, RunEnding, Termination

TIME = np.arange(0, 8.0, 0.005)
JOINTS = ("a", "b")
CONTACT_S, TRIP_S = 2.2, 6.0
EXPERIMENT = ArmContactExperiment(
    name="arm-contact", title="c", duration_s=8.0, start_rad=(0.0, 0.0),
    moves=(JointMove(1.0, 2.0, (0.0, 0.0), (0.0, 0.3)),),
    world=World(block=Block((0.4, 0.0, 0.3), (0.2, 0.2, 0.1))), pressing_joint=1,
)  # fmt: skip


def run_of(force: np.ndarray, trip_s: float | None) -> RunData:
    columns = {"time_s": TIME, "contact_force_n": force}
    for name in JOINTS:
        tripped = (trip_s <= TIME) & (name == "b") if trip_s is not None else TIME < 0
        columns[f"actuator_fault[{name}]"] = np.where(tripped, float(ActuatorFault.OVERLOAD), 0.0)
        columns[f"torque_enabled[{name}]"] = np.where(tripped, 0.0, 1.0)
    return RunData(Path("."), columns, {}, {"experiment_start_s": 0.0}, (), JOINTS)


def pressing(slope_n_per_s: float) -> np.ndarray:
    """0 N before contact, 30 N from it, then rising by `slope` from 1 s after."""
    force = np.where(TIME >= CONTACT_S, 30.0, 0.0)
    return force + np.where(TIME >= CONTACT_S + 1.0, slope_n_per_s * (TIME - CONTACT_S - 1.0), 0)


def test_contact_force_trip_of_any_joint_and_drift() -> None:
    force = pressing(0.5)
    metrics = EXPERIMENT.metrics(run_of(force, TRIP_S))
    assert metrics["contact_time_s"] == pytest.approx(CONTACT_S)
    assert metrics["overload_tripped"] is True  # joint b's, not the first joint's
    assert metrics["trip_time_after_contact_s"] == pytest.approx(TRIP_S - CONTACT_S)
    # the peak over the whole run; the mean while touching with torque on (before the trip)
    assert metrics["peak_contact_force_n"] == pytest.approx(force.max())
    on = (TIME >= CONTACT_S) & (TIME < TRIP_S)
    assert metrics["mean_contact_force_n"] == pytest.approx(force[on].mean())
    assert metrics["force_drift_n_per_s"] == pytest.approx(0.5, rel=1e-9)


def test_a_run_that_never_touches_says_why() -> None:
    metrics = EXPERIMENT.metrics(run_of(np.zeros(TIME.size), None))
    assert metrics["contact_time_s"] is None and metrics["overload_tripped"] is False
    assert metrics["mean_contact_force_n"] is None
    why = metrics["unmeasured"]["mean_contact_force_n"]
    assert why == "no contact with torque on during the run"


def entry(kind: ControllerKind, termination: Termination, metrics: dict) -> RunEntry:
    ending = RunEnding(termination)
    return RunEntry("arm-contact", ControllerChoice(kind), RunResult(Path("."), ending, metrics))


def test_predictions_a_safety_stop_of_pid_is_its_protection_acting() -> None:
    pressed = {"contact_time_s": 2.2, "overload_tripped": False, "mean_contact_force_n": 40.0}
    soft = {"contact_time_s": 2.2, "overload_tripped": False, "mean_contact_force_n": 25.0}
    pid, dob = ControllerKind.PID, ControllerKind.GC_LQR_DOB
    stopped, completed = Termination.SAFETY_STOP, Termination.COMPLETED
    entries = [
        entry(pid, stopped, pressed | {"peak_contact_force_n": 48.0}),
        entry(dob, completed, soft | {"peak_contact_force_n": 30.0}),
    ]
    relations = arm_contact_relations("arm-contact", entries)
    assert [r.holds for r in relations] == [True, True, True]
    assert "safety stop" in relations[0].ours
    # a pid that pressed on and nothing acted: the prediction fails; a DOB that tripped too
    entries[0] = entry(pid, completed, pressed | {"peak_contact_force_n": 48.0})
    tripped = soft | {"overload_tripped": True, "trip_time_after_contact_s": 1.0}
    entries[1] = entry(dob, stopped, tripped | {"peak_contact_force_n": 60.0})
    assert [r.holds for r in arm_contact_relations("arm-contact", entries)] == [False, False, False]
