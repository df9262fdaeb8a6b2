"""A comparison's plan as runs to hand out, and what its runs came to, whoever ran them.

Shared by the serial plan (hil.session.comparison) and the plan run in worker processes
(hil.session.workers), so that both report a run the same way:
- a run that raised (a bug, an unexpected error) is a run that ended in `error`: reported in the
  comparison, which is then incomplete, and the plan goes on;
- what makes every run of the plan impossible (`STOPS_THE_PLAN`: a bad configuration, a
  reference outside the joints' limits, an emulator that cannot start) stops the plan and
  reaches the command as it would from a single run (exit 2, or 1 with what to check).
"""

from __future__ import annotations

import os
import traceback
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from hil.config import ConfigError
from hil.experiments import Experiment
from hil.loop import StopFlag
from hil.output.records import RunEntry, RunResult
from hil.safety import ReferenceOutsideLimits
from hil.session.session import Session, SessionError
from hil.vocabulary import ControllerChoice, RunEnding, Termination
from sim_backend.scenario import FaultEvent

STOPS_THE_PLAN: tuple[type[Exception], ...] = (ConfigError, ReferenceOutsideLimits, SessionError)


@dataclass(frozen=True)
class PlannedRun:
    """One run of a plan: its place in the plan (from 1), what it runs, where it writes."""

    number: int
    experiment: Experiment
    choice: ControllerChoice
    out_dir: Path

    @property
    def what(self) -> str:
        return f"{self.experiment.name}: {self.choice.label}"


def planned_runs(
    plan: Sequence[tuple[Experiment, ControllerChoice]], root: Path
) -> list[PlannedRun]:
    """The plan's runs, each with its directory under the comparison's `root`."""
    return [
        PlannedRun(number, experiment, choice, root / f"{experiment.name}-{choice.dir_name}")
        for number, (experiment, choice) in enumerate(plan, start=1)
    ]


def run_planned(
    session: Session,
    run: PlannedRun,
    faults: tuple[FaultEvent, ...],
    overruns: tuple[tuple[float, float], ...],
    stop: StopFlag,
) -> RunResult:
    """One run of a plan, in this process; raises only what `STOPS_THE_PLAN`."""
    try:
        return session.run_one(
            run.experiment,
            run.choice,
            faults=faults,
            overruns=overruns,
            out_dir=run.out_dir,
            print_result=False,
            stop=stop,
        )
    except STOPS_THE_PLAN:
        raise
    except Exception as exc:  # noqa: BLE001 - reported as the run's ending, the plan goes on
        if os.environ.get("HIL_DEBUG"):
            traceback.print_exc()
        return failed_run(run, exc)


def failed_run(run: PlannedRun, exc: BaseException | str) -> RunResult:
    """The result of a run that raised instead of returning one (its directory holds what the
    loop's exit path wrote, if it got that far)."""
    text = exc if isinstance(exc, str) else f"{type(exc).__name__}: {exc}"
    return RunResult(run.out_dir, RunEnding(Termination.ERROR, text), metrics={})


def incomplete_reason(
    entries: Sequence[RunEntry], planned: int, stop_reason: str | None
) -> str | None:
    """Why the comparison is incomplete (the first run in plan order that did not run its
    course, else the plan stopped before its end), None when every run ran its course."""
    for entry in entries:
        if not entry.result.termination.ran_its_course:
            return f"{entry.experiment} / {entry.choice.label}: {entry.result.ending}"
    if len(entries) < planned:
        return f"interrupted: {stop_reason}" if stop_reason else "not every run started"
    return None


def usable_cpus() -> int:
    """The CPUs this process may run on (its affinity mask: a container or `taskset` may allow
    fewer than the machine has)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1
