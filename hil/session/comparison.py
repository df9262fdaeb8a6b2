"""The paper's testbed comparison: the experiments x the paper's controllers, then one report.

The plan (`comparison_plan`):
- contact (Fig. 5) and impact (Fig. 6): pid, gc, gc+lqr, and gc+lqr+dob with Kdist 0.5 and 1,
  then the DOB once more (Kdist 1) with the other reading of the paper's (25), so the report
  shows what the choice of reading does (the lab's accumulated total vs the literal
  uc(tk - dt));
- contact held 30 s (`contact-long`): the DOB (Kdist 1) in the configured reading and in the
  bounded one ("accumulated-integral"; the lab's "accumulated" when the bounded one is the
  configured reading, so no run is made twice): does the compliance last, or does the force
  creep?
- impact held a minute (`impact-long`): the DOB with Kdist 1 and 0.5, long enough to see the
  equilibrium behind the paper's "steady-state error".
On DYROS-JET (`--robot dyros-jet`): stand and push, each with pid, gc, gc+lqr and gc+lqr+dob
(the configuration's Kdist: the lab's stance 0.2), Sec. IV-C.
`hil run walking` (`walking_plan`): walk-slow, walk-dynamic and step-on-object, each with the
same four controllers (Kdist by phase: the configuration's on the stance leg, 1.0 on the landing
leg), Sec. IV-C, Figs. 7 and 8.
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

from controller import CompositionReading
from controller.gravity import GcCompliance
from hil.config import ConfigError, robot_of
from hil.experiments import (
    CONTACT,
    CONTACT_LONG,
    EXPERIMENTS,
    IMPACT,
    IMPACT_LONG,
    PUSH,
    STAND,
    STEP_ON_OBJECT,
    WALK_DYNAMIC,
    WALK_SLOW,
    Experiment,
)
from hil.loop import StopFlag
from hil.output.plots import ComparisonRun
from hil.output.progress import Progress
from hil.output.records import RunEntry
from hil.output.report import Report, ReportContent, write_report
from hil.output.rundir import create_run_dir, load_run, timestamp
from hil.output.strict_json import dumps
from hil.render.report_strip import FIG8_RENDERED, rendered_fig8
from hil.session.plan import (
    PlannedRun,
    incomplete_reason,
    planned_runs,
    run_planned,
    usable_cpus,
)
from hil.session.session import Session, Setup
from hil.session.workers import run_in_workers
from hil.vocabulary import ControllerChoice, ControllerKind, Termination
from sim_backend.scenario import FaultEvent

COMPARISON_CHOICES: tuple[ControllerChoice, ...] = (
    ControllerChoice(ControllerKind.PID),
    ControllerChoice(ControllerKind.GC),
    ControllerChoice(ControllerKind.GC_LQR),
    ControllerChoice(ControllerKind.GC_LQR_DOB, 0.5),
    ControllerChoice(ControllerKind.GC_LQR_DOB, 1.0),
)
# Comparisons `hil run NAME` runs by name, and the robot each is for.
NAMED_COMPARISONS: dict[str, str] = {"walking": "dyros-jet"}
OTHER_READING_KDIST = 1.0
BOUNDED_READING = CompositionReading.ACCUMULATED_INTEGRAL


@dataclass(frozen=True)
class ComparisonOutcome:
    root: Path
    report: Report
    incomplete: str | None  # why the comparison is incomplete, None when every run ran its course
    # the runs whose exit path could not turn torque off (a lost bus)
    torque_not_off: tuple[str, ...] = ()


def humanoid_choices(kdist: float) -> tuple[ControllerChoice, ...]:
    """The four controllers, and GC once more with the other reading of (8): the paper's
    literal K^-1 ("gear") beside the configuration's (the whole joint's, by default)."""
    return (
        ControllerChoice(ControllerKind.PID),
        ControllerChoice(ControllerKind.GC),
        ControllerChoice(ControllerKind.GC, gc_compliance=GcCompliance.GEAR),
        ControllerChoice(ControllerKind.GC_LQR),
        ControllerChoice(ControllerKind.GC_LQR_DOB, kdist),
    )


def humanoid_plan(kdist: float) -> list[tuple[Experiment, ControllerChoice]]:
    """DYROS-JET standing and pushed, with each of `humanoid_choices`."""
    choices = humanoid_choices(kdist)
    return [(experiment, choice) for experiment in (STAND, PUSH) for choice in choices]


def walking_plan(kdist: float) -> list[tuple[Experiment, ControllerChoice]]:
    """DYROS-JET walking slowly, dynamically and onto an object, with each of
    `humanoid_choices`."""
    choices = humanoid_choices(kdist)
    return [
        (experiment, choice)
        for experiment in (WALK_SLOW, WALK_DYNAMIC, STEP_ON_OBJECT)
        for choice in choices
    ]


def comparison_plan(
    default_reading: str, *, long_runs: bool = True
) -> list[tuple[Experiment, ControllerChoice]]:
    """The runs of the testbed comparison, in order (see the module docstring)."""
    accumulated = CompositionReading.ACCUMULATED
    other = CompositionReading.LITERAL if default_reading == accumulated else accumulated
    dob = ControllerKind.GC_LQR_DOB
    choices = [*COMPARISON_CHOICES, ControllerChoice(dob, OTHER_READING_KDIST, other)]
    plan = [(experiment, choice) for experiment in (CONTACT, IMPACT) for choice in choices]
    if long_runs:
        long_other = accumulated if default_reading == BOUNDED_READING else BOUNDED_READING
        plan += [
            (CONTACT_LONG, ControllerChoice(dob, 1.0)),
            (CONTACT_LONG, ControllerChoice(dob, 1.0, long_other)),
            (IMPACT_LONG, ControllerChoice(dob, 1.0)),
            (IMPACT_LONG, ControllerChoice(dob, 0.5)),
        ]
    return plan


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
    humanoid = robot_of(base) == "dyros-jet"
    name = "humanoid-comparison" if humanoid else "comparison"
    if named is not None:
        name = f"{named}-comparison"
    if named == "walking":
        plan = walking_plan(base.controller.kdist)
    elif humanoid:
        plan = humanoid_plan(base.controller.kdist)
    else:
        plan = comparison_plan(base.controller.composition, long_runs=long_runs)
    session.config = base
    workers = comparison_workers(session, workers, len(plan))  # refused before a directory
    root = create_run_dir(session.out_root, f"{timestamp()}-{name}")
    outcome = run_plan(
        session, plan, root, faults=faults, overruns=overruns, stop=stop, workers=workers
    )
    report = write_comparison_report(
        root,
        outcome.entries,
        session.description,
        outcome.wall_time_s,
        humanoid=humanoid,
        walking=named == "walking",
        rendered=named == "walking" and session.plots,
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
    *,
    humanoid: bool = False,
    walking: bool = False,
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
    title = (
        "DYROS-JET standing and pushed: Kim et al., ICRA 2018, Sec. IV-C"
        if humanoid
        else "Testbed comparison: Kim et al., ICRA 2018, Figs. 5 and 6"
    )
    if walking:
        title = "DYROS-JET walking: Kim et al., ICRA 2018, Sec. IV-C, Figs. 7 and 8"
    content = ReportContent(
        title=title,
        claims_source="Kim et al., ICRA 2018, Sec. III-A, IV-C"
        if humanoid
        else "Kim et al., ICRA 2018, Sec. IV-B",
        setup=setup,
        wall_time_s=wall_time_s,
        columns=tuple(columns),
    )
    return write_report(root, entries, relations, figures, problems, content)


def _experiments_of(entries: Sequence[RunEntry]) -> list[Experiment]:
    names = list(dict.fromkeys(entry.experiment for entry in entries))
    return [EXPERIMENTS[name] for name in names]
