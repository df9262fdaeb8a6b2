"""A robot's comparison: its experiments x its controllers, then one report.

Which runs, in which order, and the report's title are the robot's (its profile's
`comparisons`, hil/robots/<name>/comparison.py): `hil run` runs the configured robot's own
(the paper's testbed comparison, Figs. 5 and 6; DYROS-JET standing and pushed), `hil run NAME`
a named one (`walking`: DYROS-JET's walks, Figs. 7 and 8).
A run ending in a safety stop is a result of the comparison; one that did not run its course
(interrupted, refused at its start, a lost bus, an error) makes the comparison incomplete, and
Ctrl-C stops the whole plan.

The runs go one per CPU at a time (`run_plan`, `--workers N`; hil.session.workers), each
exactly as alone (its own emulator, seed and directory: the same log), or one after the other
in this process with `--workers 1`; the report is the same either way.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from hil.config import ConfigError
from hil.experiments import Experiment
from hil.loop import StopFlag
from hil.output.plots import ComparisonRun
from hil.output.progress import Progress
from hil.output.records import RunEntry
from hil.output.report import Report, ReportContent, write_report
from hil.output.rundir import create_run_dir, load_run, timestamp
from hil.output.strict_json import dumps
from hil.render.report_strip import FIG8_RENDERED, rendered_fig8
from hil.robots import EXPERIMENTS, Comparison, profile_of
from hil.session.plan import (
    PlannedRun,
    incomplete_reason,
    planned_runs,
    run_planned,
    usable_cpus,
)
from hil.session.session import Session, Setup
from hil.session.workers import run_in_workers
from hil.vocabulary import ControllerChoice, Termination
from sim_backend.scenario import FaultEvent


@dataclass(frozen=True)
class ComparisonOutcome:
    root: Path
    report: Report
    incomplete: str | None  # why the comparison is incomplete, None when every run ran its course
    # the runs whose exit path could not turn torque off (a lost bus)
    torque_not_off: tuple[str, ...] = ()


def run_comparison(
    session: Session,
    *,
    faults: tuple[FaultEvent, ...] = (),
    overruns: tuple[tuple[float, float], ...] = (),
    current_guard: bool = False,
    long_runs: bool = True,
    stop: StopFlag | None = None,
    named: str | None = None,
    workers: int | None = None,
) -> ComparisonOutcome:
    """Run the plan, write the report, print its table; see the module docstring.

    The software current guard is off unless asked for: the paper's experiment shows the
    actuator's own overload protection acting, and the guard would pre-empt it. `workers`: how
    many runs at a time (`comparison_workers`).
    """
    base = session.config.changed("safety", current_guard=current_guard)
    try:
        comparison = profile_of(base).comparison(named)
    except KeyError:
        raise ConfigError(
            f"`hil run {named}` is no comparison of the robot {base.model.robot!r}"
        ) from None
    plan = comparison.plan(base, long_runs)
    session.config = base
    workers = comparison_workers(session, workers, len(plan))  # refused before a directory
    root = create_run_dir(session.out_root, f"{timestamp()}-{comparison.directory}")
    outcome = run_plan(
        session, plan, root, faults=faults, overruns=overruns, stop=stop, workers=workers
    )
    report = write_comparison_report(
        root,
        outcome.entries,
        session.description,
        outcome.wall_time_s,
        comparison,
        rendered=comparison.rendered and session.plots,
    )
    print(report.table_text)
    print(report.where)
    drawn = [p for p in report.figure_paths if p.name == FIG8_RENDERED]
    if drawn:
        print(f"Fig. 8 drawn from the emulated robot: {drawn[0]}")
    if session.json_output:
        print(dumps(report.summary))
    if outcome.incomplete is not None:
        print(f"comparison incomplete: {outcome.incomplete}")
    torque_not_off = tuple(
        f"{e.experiment} / {e.choice.label}" for e in outcome.entries if e.result.torque_off_failed
    )
    return ComparisonOutcome(root, report, outcome.incomplete, torque_not_off)


@dataclass(frozen=True)
class PlanOutcome:
    entries: list[RunEntry]  # the runs that began, in plan order
    incomplete: str | None  # see `incomplete_reason`
    wall_time_s: float


def comparison_workers(session: Session, requested: int | None, runs: int) -> int:
    """How many runs at a time: `requested`, else one per CPU this process may use; never
    more than one per run nor than those CPUs (each run is three busy processes: the loop,
    its emulator, its helpers; more at once only share the CPUs and slow every run). One
    where runs cannot share the machine's setup: an attached emulator serves one run at a
    time, the live view is this process's, and wall-clock runs on the same cores would take
    each other's time (ask for more with --workers to have it anyway)."""
    if requested is not None:
        if requested < 1:
            raise ConfigError(f"--workers: must be >= 1, got {requested}")
        if requested > 1 and (session.setup is Setup.ATTACHED or session.sinks):
            raise ConfigError(
                "--workers: an attached emulator (--attach) and the live view (--live) serve "
                "one run at a time: give --workers 1"
            )
        count = min(requested, max(runs, 1), usable_cpus())
        if count < min(requested, max(runs, 1)):
            session.say(f"--workers {requested}: {count} at a time (the CPUs this may use)")
        return count
    if session.setup is Setup.ATTACHED or session.sinks or session.realtime:
        return 1
    return max(1, min(usable_cpus(), runs))


def run_plan(
    session: Session,
    plan: Sequence[tuple[Experiment, ControllerChoice]],
    root: Path,
    *,
    faults: tuple[FaultEvent, ...] = (),
    overruns: tuple[tuple[float, float], ...] = (),
    stop: StopFlag | None = None,
    workers: int | None = None,
) -> PlanOutcome:
    """The plan's runs into `root`, `workers` at a time (`comparison_workers`); Ctrl-C or
    SIGTERM stops the whole plan. A bar with an ETA on a terminal, lines otherwise."""
    runs = planned_runs(plan, root)
    count = comparison_workers(session, workers, len(runs))
    own_stop = stop is None
    if stop is None:
        stop = StopFlag()
        stop.install()
    started = time.perf_counter()
    bar = Progress(
        len(runs), unit="runs", desc="comparison", enabled=False if session.quiet else None
    )
    session.progress = bar
    try:
        if count > 1:
            entries = run_in_workers(
                session, runs, count, faults=faults, overruns=overruns, stop=stop, bar=bar
            )
        else:
            entries = _run_serially(session, runs, faults, overruns, stop, bar)
    finally:
        bar.close()
        session.progress = None
        if own_stop:
            stop.restore()
    incomplete = incomplete_reason(entries, len(runs), stop.reason)
    return PlanOutcome(entries, incomplete, time.perf_counter() - started)


def _run_serially(
    session: Session,
    runs: Sequence[PlannedRun],
    faults: tuple[FaultEvent, ...],
    overruns: tuple[tuple[float, float], ...],
    stop: StopFlag,
    bar: Progress,
) -> list[RunEntry]:
    """The runs in order, in this process, until one is interrupted."""
    entries: list[RunEntry] = []
    for run in runs:
        if stop.reason is not None:
            break
        what = f"[{run.number}/{len(runs)}] {run.what}"
        session.progress_done = run.number - 1
        if bar.enabled:
            bar.update_to(run.number - 1, what)
        else:
            session.say(what)
        result = run_planned(session, run, faults, overruns, stop)
        entries.append(RunEntry(run.experiment.name, run.choice, result))
        bar.update_to(run.number)
        if result.termination is Termination.INTERRUPTED:
            break
    return entries


def write_comparison_report(
    root: Path,
    entries: Sequence[RunEntry],
    setup: str,
    wall_time_s: float,
    comparison: Comparison,
    *,
    rendered: bool = False,
) -> Report:
    """The report of the comparison (figures, relations, tables) for these runs; rendered:
    with the robot drawn at Fig. 8's instants (hil/render/report_strip.py)."""
    relations = []
    figures: list[Path] = []
    problems: list[str] = []
    columns = []
    for experiment in _experiments_of(entries):
        mine = [e for e in entries if e.experiment == experiment.name]
        relations += experiment.relations(entries)
        known = {c.key for c in columns}
        columns += [c for c in experiment.report_columns if c.key not in known]
        runs = []
        for entry in mine:
            try:
                data = load_run(entry.result.out_dir)
            except (OSError, ValueError) as exc:
                problems.append(f"{experiment.name} / {entry.choice.label}: {exc}")
                continue
            if len(data.time_s) > 1:
                runs.append(ComparisonRun(entry.choice, data))
        try:
            path = experiment.comparison_figure(runs, root / experiment.figure_name, setup)
        except (KeyError, ValueError, OSError) as exc:  # OSError: a full disk
            problems.append(f"{experiment.figure_name}: {exc}")
            continue
        if path is not None:
            figures.append(path)
    if rendered:
        drawn, missing = rendered_fig8(root, entries)
        figures += drawn
        problems += missing
    content = ReportContent(
        title=comparison.title,
        claims_source=comparison.claims_source,
        setup=setup,
        wall_time_s=wall_time_s,
        columns=tuple(columns),
    )
    return write_report(root, entries, relations, figures, problems, content)


def _experiments_of(entries: Sequence[RunEntry]) -> list[Experiment]:
    names = list(dict.fromkeys(entry.experiment for entry in entries))
    return [EXPERIMENTS[name] for name in names]
