"""A comparison's plan run by worker processes (hil.session.workers) on the in-process setup:
results in plan order, a run that raises reported as a failed run (the plan goes on) the same
way with one worker as with two, what stops the plan stopping it, how many workers."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from hil.config import ConfigError, load_config
from hil.experiments import IMPACT
from hil.experiments.impact import ImpactExperiment
from hil.session import Session, SessionError, Setup
from hil.session.comparison import comparison_workers, run_plan
from hil.vocabulary import ControllerChoice, ControllerKind, Termination

CONFIG = load_config()
PID = ControllerChoice(ControllerKind.PID)
GC = ControllerChoice(ControllerKind.GC)
SHORT = dataclasses.replace(IMPACT, duration_s=0.3)


@dataclasses.dataclass(frozen=True)
class Broken(ImpactExperiment):
    """An impact whose reference raises (a bug in an experiment): it reaches the worker by
    pickle, so it lives at module level."""

    error: type[Exception] = RuntimeError

    def reference(self, time_s: float) -> float:
        raise self.error("the reference is broken")


def _session(tmp_path: Path) -> Session:
    return Session(CONFIG, Setup.IN_PROCESS, out_root=tmp_path, quiet=True, plots=False)


@pytest.mark.parametrize("workers", [1, 2])
def test_a_run_that_raises_is_a_failed_run_and_the_plan_goes_on(
    tmp_path: Path, workers: int
) -> None:
    broken = dataclasses.replace(Broken(**vars(SHORT)), name="impact")
    plan = [(SHORT, PID), (broken, GC), (SHORT, ControllerChoice(ControllerKind.GC_LQR))]
    outcome = run_plan(_session(tmp_path), plan, tmp_path, workers=workers)
    assert [(e.choice, e.result.termination) for e in outcome.entries] == [
        (PID, Termination.COMPLETED),
        (GC, Termination.ERROR),
        (ControllerChoice(ControllerKind.GC_LQR), Termination.COMPLETED),
    ]
    failed = outcome.entries[1].result
    assert failed.ending.detail == "RuntimeError: the reference is broken"
    assert failed.out_dir == tmp_path / "impact-gc"
    assert outcome.incomplete == "impact / gc: error: RuntimeError: the reference is broken"
    assert (tmp_path / "impact-gc-lqr" / "summary.json").is_file()


def test_what_makes_every_run_impossible_stops_the_plan_as_it_does_alone(tmp_path: Path) -> None:
    broken = dataclasses.replace(Broken(**vars(SHORT)), error=SessionError)
    plan = [(broken, PID), (SHORT, GC), (SHORT, PID), (SHORT, GC)]
    with pytest.raises(SessionError, match="the reference is broken"):
        run_plan(_session(tmp_path), plan, tmp_path, workers=2)


def test_the_results_come_back_in_plan_order_whatever_order_the_runs_end_in(
    tmp_path: Path,
) -> None:
    # the longest run is handed out first and ends last: it is still second in the plan
    longer = dataclasses.replace(SHORT, duration_s=1.5)
    lqr = ControllerChoice(ControllerKind.GC_LQR)
    plan = [(SHORT, PID), (longer, GC), (SHORT, lqr)]
    outcome = run_plan(_session(tmp_path), plan, tmp_path, workers=2)
    assert outcome.incomplete is None
    assert [(e.choice, e.result.out_dir.name, e.result.ticks) for e in outcome.entries] == [
        (PID, "impact-pid", outcome.entries[0].result.ticks),
        (GC, "impact-gc", outcome.entries[0].result.ticks + 240),  # 1.2 s more at 200 Hz
        (lqr, "impact-gc-lqr", outcome.entries[0].result.ticks),
    ]


def test_how_many_workers(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("hil.session.comparison.usable_cpus", lambda: 2)
    session = Session(CONFIG, Setup.EMBEDDED, out_root=tmp_path)
    assert comparison_workers(session, None, 16) == 2  # one per CPU
    assert comparison_workers(session, None, 1) == 1  # at most one per run
    assert comparison_workers(session, 1, 16) == 1  # asked for
    assert comparison_workers(dataclasses.replace(session, realtime=True), None, 16) == 1
    attached = dataclasses.replace(session, setup=Setup.ATTACHED, attach={})
    assert comparison_workers(attached, None, 16) == 1
    with pytest.raises(ConfigError, match="--attach"):
        comparison_workers(attached, 2, 16)
    with pytest.raises(ConfigError, match=">= 1"):
        comparison_workers(session, 0, 16)


def test_workers_asked_for_are_at_most_one_per_usable_cpu(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`hil run --robot dyros-jet --workers 1000` ran 10 at once on 2 CPUs (issue 25)."""
    monkeypatch.setattr("hil.session.comparison.usable_cpus", lambda: 2)
    session = Session(CONFIG, Setup.EMBEDDED, out_root=tmp_path, quiet=True)
    assert comparison_workers(session, 1000, 10) == 2
    assert comparison_workers(session, 3, 16) == 2
    assert comparison_workers(session, 2, 16) == 2


def test_a_humanoid_lqr_run_designs_its_gains_in_a_worker(tmp_path: Path) -> None:
    """A DYROS-JET gc+lqr run starts a process of its own (the LQR's designer, and the log
    writer): in a worker it does so as alone (a daemonic worker could not: "daemonic processes
    are not allowed to have children"), with one worker and with two."""
    from hil.experiments import STAND

    stand = dataclasses.replace(STAND, duration_s=0.3)
    config = load_config(robot="dyros-jet")
    session = Session(config, Setup.IN_PROCESS, out_root=tmp_path, quiet=True, plots=False)
    lqr = ControllerChoice(ControllerKind.GC_LQR)
    for workers in (1, 2):
        out = tmp_path / str(workers)
        outcome = run_plan(session, [(stand, lqr), (stand, GC)], out, workers=workers)
        assert [e.result.termination for e in outcome.entries] == [Termination.COMPLETED] * 2, [
            e.result.ending.text for e in outcome.entries
        ]
