"""The comparison report and the plots, from small synthetic run logs written with RunLog.

Each synthetic run is built to satisfy or to violate one of the paper's relations by
construction (a force that holds at a chosen level, a trip at a chosen delay, a damped ringing
with a chosen amplitude, decay and offset); the report must mark each relation accordingly.
The metrics are computed from the logs by the experiments, as the loop does.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from hil.experiments import CONTACT, IMPACT, Experiment
from hil.output import PER_JOINT_COLUMNS, RunEntry, RunLog, RunResult, load_run
from hil.output.plots import plot_run
from hil.output.report import Relation
from hil.robots import profile
from hil.session.comparison import write_comparison_report
from hil.vocabulary import (
    ControllerChoice,
    Reaction,
    RunEnding,
    SafetyCause,
    SafetyEvent,
    Termination,
)

TESTBED = profile("testbed").comparison()  # the testbed's own comparison and report
pytestmark = pytest.mark.timeout(60)

PERIOD_S = 0.01  # coarser than 200 Hz: keeps the files small, the metrics do not care
OVERLOAD = 0x01  # ActuatorFault.OVERLOAD in the log's actuator_fault column
VERSIONS = {"numpy": "9.9.9-test", "flexjoint-hil": "0.0.0-test"}


@dataclass(frozen=True)
class ContactRun:
    """A contact run: the force rises to `hold_force_n` after contact; optionally a trip."""

    controller: str
    kdist: float
    hold_force_n: float
    trip_after_contact_s: float | None = None
    contact_s: float = 2.3


@dataclass(frozen=True)
class ImpactRun:
    """An impact run: link = -offset - amplitude e^(-t/decay) sin(2 pi f t) after the push."""

    controller: str
    kdist: float
    amplitude_rad: float
    decay_s: float
    offset_rad: float
    ringing_hz: float = 3.0


def _meta(experiment: Experiment, controller: str, kdist: float, seed: int = 7) -> dict:
    return {
        "experiment": experiment.name,
        "controller": controller,
        "controller_label": ControllerChoice(controller, kdist).label,
        "kdist": kdist,
        "setup": "synthetic",
        "seed": seed,
        "python": "3.11.test",
        "packages": VERSIONS,
        "config": {
            "joints": [{"name": "testbed", "dynamixel_id": 1, "encoder_node_id": 5}],
            "controller": {"composition": "accumulated"},
            "safety": {"current_guard": False},
            "source": "<synthetic>",
        },
    }


def _write(
    out_dir: Path,
    experiment: Experiment,
    controller: str,
    kdist: float,
    link: np.ndarray,
    force: np.ndarray,
    hardware_error: np.ndarray,
    joint_names: tuple[str, ...] = ("testbed",),
) -> dict[str, np.ndarray]:
    time = np.arange(link.size) * PERIOD_S
    n = len(joint_names)
    with RunLog(out_dir, joint_names, _meta(experiment, controller, kdist)) as log:
        log.event(0.0, "open", "bus open")
        for k, t in enumerate(time):
            torque = hardware_error[k] == 0
            motor = link[k] + 0.003
            joints = {c: np.zeros(n) for c in PER_JOINT_COLUMNS}
            joints.update(
                reference_rad=np.full(n, experiment.reference(float(t))),
                goal_rad=np.full(n, experiment.reference(float(t))),
                motor_angle_rad=np.full(n, motor),
                link_angle_rad=np.full(n, link[k]),
                deflection_rad=np.full(n, link[k] - motor),
                motor_current_a=np.full(n, -force[k] / 10.0),
                actuator_fault=np.full(n, hardware_error[k]),
                torque_enabled=np.full(n, 1 if torque else 0),
                motor_valid=np.ones(n),
                link_valid=np.ones(n),
            )
            log.write_row(
                k,
                t,
                (force[k],),
                "run" if torque else "torque_off",
                "experiment",
                0,
                [joints[c] for c in PER_JOINT_COLUMNS],
                math.nan,
                PERIOD_S,
            )
        trips = np.flatnonzero(hardware_error)
        if trips.size:
            t_trip = float(time[trips[0]])
            log.event(t_trip, "hardware_error", "Overload", joint="testbed", action="torque_off")
            log.event(t_trip, "torque_off", "safety stop: torque off")
    return load_run(out_dir).columns


def _result(out_dir: Path, metrics: dict, tripped_at: float | None) -> RunResult:
    if tripped_at is None:
        return RunResult(out_dir, RunEnding(Termination.COMPLETED), metrics, [], 10, 0.1)
    event = SafetyEvent(
        0,
        tripped_at,
        SafetyCause.HARDWARE_ERROR,
        "testbed",
        Reaction.TORQUE_OFF,
        "Overload",
    )
    ending = RunEnding(Termination.SAFETY_STOP, "hardware_error (torque_off)")
    return RunResult(out_dir, ending, metrics, [event], 10, 0.1)


def _entry(experiment: Experiment, spec: ContactRun | ImpactRun, result: RunResult) -> RunEntry:
    return RunEntry(experiment.name, ControllerChoice(spec.controller, spec.kdist), result)


def check_relations(entries: list[RunEntry]) -> list[Relation]:
    return [*CONTACT.relations(entries), *IMPACT.relations(entries)]


def write_contact(root: Path, spec: ContactRun) -> RunEntry:
    time = np.arange(int(CONTACT.duration_s / PERIOD_S)) * PERIOD_S
    since = time - spec.contact_s
    force = np.where(since >= 0, spec.hold_force_n * np.clip(0.2 + since / 0.3, 0, 1), 0.0)
    link = np.maximum([CONTACT.reference(float(t)) for t in time], -0.2)
    errors = np.zeros(time.size, dtype=int)
    trip = None
    if spec.trip_after_contact_s is not None:
        trip = spec.contact_s + spec.trip_after_contact_s
        errors[time >= trip - 1e-9] = OVERLOAD
        force = np.where(time >= trip - 1e-9, 5.0, force)
    out_dir = root / f"contact-{spec.controller}-{spec.kdist:g}"
    _write(out_dir, CONTACT, spec.controller, spec.kdist, link, force, errors)
    metrics = CONTACT.metrics(load_run(out_dir))
    return _entry(CONTACT, spec, _result(out_dir, metrics, trip))


def write_impact(root: Path, spec: ImpactRun) -> RunEntry:
    push = IMPACT.world.pushes[0]
    time = np.arange(int(IMPACT.duration_s / PERIOD_S)) * PERIOD_S
    since = np.maximum(time - push.start_s, 0.0)
    ringing = np.exp(-since / spec.decay_s) * np.sin(2 * np.pi * spec.ringing_hz * since)
    link = -spec.offset_rad - spec.amplitude_rad * ringing
    force = np.zeros(time.size)
    out_dir = root / f"impact-{spec.controller}-{spec.kdist:g}"
    _write(out_dir, IMPACT, spec.controller, spec.kdist, link, force, np.zeros(time.size, int))
    metrics = IMPACT.metrics(load_run(out_dir))
    return _entry(IMPACT, spec, _result(out_dir, metrics, None))


# The paper's Sec. IV-B, by construction: pid presses hard and trips 1.5 s after contact, the
# DOB holds 20-40 N; after the push pid rings slowly, the DOB peaks higher and settles fast, and
# Kdist = 1 leaves a larger offset than 0.5.
PAPER_LIKE_CONTACT = (
    ContactRun("pid", 0.0, 85.0, 1.5),
    ContactRun("gc", 0.0, 82.0, 1.6),
    ContactRun("gc+lqr", 0.0, 78.0, 1.7),
    ContactRun("gc+lqr+dob", 0.5, 38.0),
    ContactRun("gc+lqr+dob", 1.0, 26.0),
)
PAPER_LIKE_IMPACT = (
    ImpactRun("pid", 0.0, 0.04, 1.0, 0.001),
    ImpactRun("gc", 0.0, 0.04, 0.9, 0.001),
    ImpactRun("gc+lqr", 0.0, 0.06, 0.1, 0.0005),
    ImpactRun("gc+lqr+dob", 0.5, 0.12, 0.08, 0.0012),
    ImpactRun("gc+lqr+dob", 1.0, 0.2, 0.08, 0.0021),
)
# Everything the other way round.
CONTRARY_CONTACT = (
    ContactRun("pid", 0.0, 50.0, None),
    ContactRun("gc+lqr+dob", 0.5, 90.0, 0.8),
    ContactRun("gc+lqr+dob", 1.0, 60.0, None),
)
CONTRARY_IMPACT = (
    ImpactRun("pid", 0.0, 0.2, 0.05, 0.001),
    ImpactRun("gc+lqr", 0.0, 0.04, 1.0, 0.001),
    ImpactRun("gc+lqr+dob", 0.5, 0.06, 1.0, 0.003),
    ImpactRun("gc+lqr+dob", 1.0, 0.04, 1.0, 0.001),
)


def _verdicts(relations: list[Relation]) -> dict[str, bool | None]:
    return {r.claim: r.holds for r in relations}


def _one(relations: list[Relation], *words: str) -> Relation:
    found = [r for r in relations if all(w in r.claim for w in words)]
    assert len(found) == 1, f"{words}: {[r.claim for r in relations]}"
    return found[0]


@pytest.fixture(scope="module")
def paper_like(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list]:
    root = tmp_path_factory.mktemp("paper_like")
    results = [write_contact(root, s) for s in PAPER_LIKE_CONTACT]
    results += [write_impact(root, s) for s in PAPER_LIKE_IMPACT]
    return root, results


@pytest.fixture(scope="module")
def contrary(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list]:
    root = tmp_path_factory.mktemp("contrary")
    results = [write_contact(root, s) for s in CONTRARY_CONTACT]
    results += [write_impact(root, s) for s in CONTRARY_IMPACT]
    return root, results


def test_the_synthetic_logs_are_what_they_claim(paper_like: tuple[Path, list]) -> None:
    """Guard on the construction itself, so the verdict tests below test the checker."""
    _, results = paper_like
    by = {(e.experiment, str(e.choice.kind), e.choice.kdist): e.result.metrics for e in results}
    pid = by[("contact", "pid", 0.0)]
    assert pid["overload_tripped"] and pid["trip_time_after_contact_s"] == pytest.approx(1.5)
    assert pid["peak_contact_force_n"] == pytest.approx(85.0)
    assert not by[("contact", "gc+lqr+dob", 1.0)]["overload_tripped"]
    ringing = by[("impact", "pid", 0.0)]
    fast = by[("impact", "gc+lqr+dob", 1.0)]
    assert ringing["oscillations"] >= 4 and fast["settling_time_s"] < ringing["settling_time_s"]
    assert fast["first_peak_rad"] > ringing["first_peak_rad"]


def test_every_relation_holds_for_paper_like_runs(paper_like: tuple[Path, list]) -> None:
    _, results = paper_like
    relations = check_relations(results)
    assert len(relations) == 13
    failing = [(r.claim, r.ours, r.note) for r in relations if r.holds is not True]
    assert not failing


def test_every_relation_fails_for_contrary_runs(contrary: tuple[Path, list]) -> None:
    _, results = contrary
    relations = check_relations(results)
    verdicts = _verdicts(relations)
    assert None not in verdicts.values(), [(r.claim, r.note) for r in relations]
    assert not any(verdicts.values()), [r.claim for r in relations if r.holds]
    compliant = _one(relations, "Kdist 0.5", "stays compliant")
    assert "TRIPPED" in compliant.ours


def test_pid_trip_far_from_1_5_s_after_contact_does_not_hold(tmp_path: Path) -> None:
    results = [write_contact(tmp_path, ContactRun("pid", 0.0, 85.0, trip_after_contact_s=3.5))]
    relations = check_relations(results)
    assert _one(relations, "pid", "overload protection").holds is False
    assert _one(relations, "pid", "70 N").holds is True  # the force relation is independent
    assert "3.50 s after contact" in _one(relations, "pid", "overload protection").ours


def test_missing_or_incomplete_runs_are_not_checked(paper_like: tuple[Path, list]) -> None:
    _, results = paper_like
    without_pid = [e for e in results if e.choice.kind != "pid"]
    relations = check_relations(without_pid)
    pid_trip = _one(relations, "pid", "overload protection")
    assert pid_trip.holds is None and "no pid run" in pid_trip.note
    assert _one(relations, "steady-state").holds is True  # does not need pid

    broken = []
    for entry in results:
        choice = entry.choice
        if choice.kind == "gc+lqr+dob" and choice.kdist == 0.5 and entry.experiment == "impact":
            ending = RunEnding(Termination.BUS_FAILURE, "no reply")
            entry = RunEntry(entry.experiment, choice, RunResult(entry.result.out_dir, ending, {}))
        broken.append(entry)
    steady = _one(check_relations(broken), "steady-state")
    assert steady.holds is None and "ended early: bus failure" in steady.note


def test_write_report_creates_the_files_and_says_where_they_came_from(
    paper_like: tuple[Path, list],
) -> None:
    root, results = paper_like
    report = write_comparison_report(root, results, "synthetic setup", 12.5, TESTBED)
    for name in ("report.md", "report.json", "fig5_contact.png", "fig6_impact.png"):
        path = root / name
        assert path.is_file() and path.stat().st_size > 0, name
    assert (root / "fig5_contact.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert report.markdown_path == root / "report.md"
    markdown = report.markdown_path.read_text()
    assert "synthetic setup" in markdown and "seed: 7" in markdown
    assert "numpy 9.9.9-test" in markdown
    for entry in results:
        assert f"`{entry.result.out_dir.name}/`" in markdown
    assert markdown.count("**holds**") == 13
    # the terminal table: every run, how it ended, the relations
    text = report.table_text
    assert "gc+lqr+dob (Kdist 0.5)" in text and "safety stop: hardware_error" in text
    assert "13 hold, 0 do not hold, 0 not checked" in text
    # the JSON summary is what report.json holds
    on_disk = json.loads((root / "report.json").read_text())
    assert on_disk["relation_counts"] == {"holds": 13, "does not hold": 0, "not checked": 0}
    assert report.summary["seed"] == 7 and len(on_disk["runs"]) == len(results)
    # the summary in memory is exactly what report.json holds (was: `assert json.dumps(...)`,
    # true for any non-empty string)
    assert json.loads(json.dumps(report.summary, default=str)) == on_disk


def test_report_marks_failures_in_markdown_and_text(contrary: tuple[Path, list]) -> None:
    root, results = contrary
    report = write_comparison_report(root, results, "synthetic setup", 1.0, TESTBED)
    markdown = report.markdown_path.read_text()
    assert "**does not hold**" in markdown and "**holds**" not in markdown
    assert "[does not hold]" in report.table_text


def test_plot_run_writes_a_png_for_each_experiment(paper_like: tuple[Path, list]) -> None:
    _, results = paper_like
    for entry in (results[0], results[-1]):
        experiment = CONTACT if entry.experiment == "contact" else IMPACT
        run = load_run(entry.result.out_dir)
        paths = plot_run(run, experiment.marks(run))
        assert paths == [entry.result.out_dir / "plot.png"]
        assert paths[0].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_plot_run_draws_each_joint_of_a_multi_joint_log(tmp_path: Path) -> None:
    size = 200
    link = -0.01 * np.sin(np.arange(size) * 0.05)
    _write(
        tmp_path,
        IMPACT,
        "pid",
        0.0,
        link,
        np.zeros(size),
        np.zeros(size, int),
        joint_names=("hip", "knee"),
    )
    run = load_run(tmp_path)
    assert run.joint_names == ("hip", "knee")
    paths = plot_run(run, IMPACT.marks(run))
    assert [p.name for p in paths] == ["plot-hip.png", "plot-knee.png"]
    assert all(p.is_file() for p in paths)


def test_plot_run_says_what_is_missing(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="no log.csv"):
        load_run(tmp_path)


def test_a_dob_run_that_trips_is_not_compliant_even_at_a_small_force(tmp_path: Path) -> None:
    results = [
        write_contact(tmp_path, ContactRun("gc+lqr+dob", 1.0, 30.0, trip_after_contact_s=0.8)),
        write_contact(tmp_path, ContactRun("pid", 0.0, 85.0, trip_after_contact_s=1.5)),
    ]
    relations = check_relations(results)
    compliant = _one(relations, "Kdist 1", "stays compliant")
    assert compliant.holds is False and "TRIPPED" in compliant.ours
    assert _one(relations, "Kdist 1", "less than pid").holds is True


def test_the_report_lists_only_the_files_a_run_has(
    paper_like: tuple[Path, list], tmp_path: Path
) -> None:
    """Issue 25: report.md listed a summary.json that a killed worker's run does not have."""
    _, results = paper_like
    entries = []
    for name, files in (("whole-run", 3), ("killed-run", 2)):
        out_dir = tmp_path / name
        out_dir.mkdir()
        for file in ("log.csv", "events.jsonl"):
            (out_dir / file).write_bytes((results[0].result.out_dir / file).read_bytes())
        if files == 3:
            (out_dir / "summary.json").write_text("{}")
        ending = RunEnding(Termination.ERROR, "the worker process died")
        entries.append(RunEntry("impact", results[0].choice, RunResult(out_dir, ending, {})))
    report = write_comparison_report(tmp_path, entries, "synthetic setup", 1.0, TESTBED)
    lines = report.markdown_path.read_text().splitlines()
    (killed,) = [line for line in lines if "`killed-run/`" in line]
    assert "(log.csv, events.jsonl)" in killed and "no summary.json" in killed, killed
    (whole,) = [line for line in lines if "`whole-run/`" in line]
    assert whole.endswith("(log.csv, events.jsonl, summary.json)"), whole
