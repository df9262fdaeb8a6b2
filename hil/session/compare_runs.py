"""`hil compare`: any runs of one experiment, from their directories, side by side.

`compare_runs(paths, out_dir)` loads every run (hil/output/run_data.py), refuses what cannot be
compared (`NotComparable`: a path that is not a run directory, runs of different experiments,
fewer than two runs, one run given twice), and writes into `out_dir`:

    report.md     the runs' metrics side by side (the experiment's report columns, then any
                  other numeric metric), how long each ran and how it ended (a safety stop
                  with its time; a missing or torn summary.json), what differs between their
                  records (controller, parameters, seed, configuration), the figures
    figures       the experiment's own comparison figure when it is a built-in one (the
                  paper's Figs. 5-8), and the overlays of hil/output/overlay_plots.py (signals
                  per joint; on the humanoid the joints' grid and the ZMP, pelvis tilt and
                  support margin of kinematics.csv)

and returns a `Comparison` whose `table_text` is what `hil compare` prints.

Runs are named by their record's label (meta.json's controller_label: 'gc+lqr+dob (Kdist 1)',
a plug-in's class name), never by an enum, so any controller compares; where two runs share a
label the directory's name is added. The paper's controllers keep the paper's line styles
(hil/output/plots.py) while they are distinct; every other run gets a colour of its own.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from controller import COMPOSITION_READINGS
from hil.experiments import Experiment
from hil.output.overlay_plots import OverlayRun, overlay_figures
from hil.output.plots import ComparisonRun, LineStyle, comparison_style
from hil.output.report import markdown_table, metric_columns, plain_table
from hil.output.run_data import NotARunDirectory, Run, load_run
from hil.output.rundir import create_run_dir, timestamp
from hil.robots import EXPERIMENTS
from hil.vocabulary import ControllerChoice, ControllerKind, ControllerRef

# meta.json's entries that say how two runs differ (beyond when and where they ran)
_COMPARED_META = (
    "controller_label",
    "controller_spec",
    "controller_params",
    "kdist",
    "reading",
    "gc_compliance",
    "experiment_parameters",
    "setup",
    "clock",
    "seed",
    "faults",
    "overruns",
    "config_source",
    "config",
)
_MAX_DIFFERENCES = 40
_COLOURS = ("tab:blue", "tab:red", "tab:green", "tab:orange", "tab:purple", "tab:brown",
            "tab:pink", "tab:olive", "tab:cyan", "0.3")  # fmt: skip
_LINESTYLES = ("-", "--", "-.", ":")


class NotComparable(ValueError):
    """These paths cannot be compared (`hil compare` exits 2): the message says why."""


@dataclass(frozen=True)
class Comparison:
    """What `compare_runs` wrote: the runs as drawn, the report, its figures and problems."""

    experiment: str
    runs: tuple[OverlayRun, ...]
    out_dir: Path
    report_path: Path
    figures: tuple[Path, ...]
    problems: tuple[str, ...]
    table_text: str


def load_runs(paths: Sequence[str | os.PathLike[str]]) -> list[Run]:
    """Every run of `paths`, loaded, or `NotComparable` saying which path is wrong and why."""
    if len(paths) < 2:
        raise NotComparable(f"give two or more run directories to compare (got {len(paths)})")
    runs: list[Run] = []
    seen: dict[Path, str] = {}
    for path in paths:
        try:
            run = load_run(path)
        except NotARunDirectory as exc:
            raise NotComparable(str(exc)) from None
        where = Path(path).resolve()
        if where in seen:
            also = f" (also as {seen[where]})" if seen[where] != str(path) else ""
            raise NotComparable(f"{path} is given twice{also}")
        seen[where] = str(path)
        if not run.experiment:
            raise NotComparable(f"{path} records no experiment (no meta.json): not a hil run")
        runs.append(run)
    by_experiment: dict[str, list[str]] = {}
    for path, run in zip(paths, runs, strict=True):
        by_experiment.setdefault(run.experiment, []).append(str(path))
    if len(by_experiment) > 1:
        named = "; ".join(f"{name}: {', '.join(where)}" for name, where in by_experiment.items())
        raise NotComparable(f"runs of different experiments cannot be compared ({named})")
    return runs


def compare_runs(
    paths: Sequence[str | os.PathLike[str]],
    out_dir: str | os.PathLike[str] | None = None,
    *,
    out_root: str | os.PathLike[str] = "runs",
) -> Comparison:
    """Compare the runs at `paths` (module docstring) into `out_dir` (default: a new
    `out_root/TIMESTAMP-compare-EXPERIMENT`)."""
    runs = load_runs(paths)
    name = runs[0].experiment
    if out_dir is None:
        out = create_run_dir(Path(out_root), f"{timestamp()}-compare-{_slug(name)}")
    else:
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
    choices = [_choice(run) for run in runs]
    entries = [
        OverlayRun(run, label, style)
        for run, label, style in zip(runs, _labels(runs), _styles(choices), strict=True)
    ]
    title = str(runs[0].meta.get("experiment_title") or name)
    setups = {str(run.meta.get("setup", "")) for run in runs}
    setup = setups.pop() if len(setups) == 1 else ""
    figures: list[Path] = []
    problems: list[str] = []
    experiment = _built_in(runs[0])
    if experiment is not None:
        drawn = [
            ComparisonRun(choice, entry.run.data, entry.label, entry.style)
            for choice, entry in zip(choices, entries, strict=True)
        ]
        try:
            path = experiment.comparison_figure(drawn, out / experiment.figure_name, setup)
        except Exception as exc:  # noqa: BLE001 - a figure must not cost the comparison
            problems.append(f"{experiment.figure_name}: {type(exc).__name__}: {exc}")
        else:
            figures += [path] if path is not None else []
    overlays = overlay_figures(entries, out, title)
    figures += overlays.paths
    problems += overlays.problems
    header, rows = _table(entries, experiment)
    report = out / "report.md"
    report.write_text(_markdown(out, name, title, setup, entries, header, rows, figures, problems))
    text = "\n".join(
        [
            f"hil compare: {len(runs)} runs of {name} ({title})",
            "",
            plain_table(header, rows),
            "",
            *(f"  #{n}: {entry.run.path}" for n, entry in enumerate(entries, 1)),
            *(f"  note: {problem}" for problem in problems),
            f"report: {report}",
        ]
    )
    return Comparison(name, tuple(entries), out, report, tuple(figures), tuple(problems), text)


# --- the runs as drawn ------------------------------------------------------------------------
def _choice(run: Run) -> ControllerChoice:
    """The controller choice the record names (for the paper's line styles); a controller the
    paper does not have, or a record that does not parse, is a plain reference to it."""
    meta = run.meta
    name = str(meta.get("controller") or run.controller)
    spec = str(meta.get("controller_spec") or name)
    if ":" not in spec and name in {kind.value for kind in ControllerKind}:
        kind = ControllerKind(name)
        reading = meta.get("reading")
        try:
            return ControllerChoice(
                kind,
                float(meta.get("kdist") or 0.0),
                reading if kind.has_lqr and reading in COMPOSITION_READINGS else None,
            )
        except ValueError:
            pass
    return ControllerChoice(ControllerRef(name=name, spec=spec))


def _labels(runs: Sequence[Run]) -> list[str]:
    """Each run's record label, with its directory's name where two runs share a label."""
    labels = [run.controller for run in runs]
    return [
        f"{label} ({run.path.name})" if labels.count(label) > 1 else label
        for label, run in zip(labels, runs, strict=True)
    ]


def _styles(choices: Sequence[ControllerChoice]) -> list[LineStyle]:
    """The paper's style for its controllers while distinct; for every other run a colour no
    other run has (then a colour and line style no other run has)."""
    styles: list[LineStyle | None] = []
    for choice in choices:
        style = comparison_style(choice) if choice.kind is not None else None
        taken = {(s.color, s.linestyle) for s in styles if s is not None}
        styles.append(
            style if style is not None and (style.color, style.linestyle) not in taken else None
        )
    pairs = [(colour, line) for line in _LINESTYLES for colour in _COLOURS]
    chosen: list[LineStyle] = []
    for number, style in enumerate(styles):
        if style is None:
            others = [s for s in (*chosen, *styles[number + 1 :]) if s is not None]
            colours = {s.color for s in others}
            free = (
                [(c, "-") for c in _COLOURS if c not in colours]
                or [p for p in pairs if p not in {(s.color, s.linestyle) for s in others}]
                or [pairs[number % len(pairs)]]
            )
            style = LineStyle(*free[0], 1.6, 1.0, True)
        chosen.append(style)
    return chosen


def _built_in(run: Run) -> Experiment | None:
    """The built-in experiment the run is of (by name and title: a plug-in may share a name)."""
    experiment = EXPERIMENTS.get(run.experiment)
    title = run.meta.get("experiment_title")
    if experiment is None or (title is not None and title != experiment.title):
        return None
    return experiment


def _slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9.-]+", "-", name).strip("-") or "runs"


# --- the table and the report -----------------------------------------------------------------
def _table(
    entries: Sequence[OverlayRun], experiment: Experiment | None
) -> tuple[list[str], list[list[str]]]:
    known = experiment.report_columns if experiment is not None else ()
    columns = metric_columns([entry.run.metrics for entry in entries], known)
    header = ["#", "controller", *(c.header for c in columns), "ran [s]", "ended"]
    rows = [
        [
            str(number),
            entry.label,
            *(c.fmt(entry.run.metrics.get(c.key)) for c in columns),
            f"{entry.run.time_s[-1]:.2f}" if entry.run.ticks else "-",
            _ended(entry.run),
        ]
        for number, entry in enumerate(entries, 1)
    ]
    return header, rows


def _ended(run: Run) -> str:
    """How the run ended: its termination, the first safety stop's time, or why unknown."""
    if run.summary_problem is not None:
        return f"unknown: {run.summary_problem}"
    events = run.safety_events
    if events and not run.completed and "time_s" in events[0]:
        return f"{run.termination} at {float(events[0]['time_s']):.3f} s"
    return run.termination


def _differences(entries: Sequence[OverlayRun]) -> list[str]:
    """What the runs' records (meta.json) say differently, one line per entry."""
    flat = [_flatten({k: e.run.meta.get(k) for k in _COMPARED_META}) for e in entries]
    keys = list(dict.fromkeys(key for record in flat for key in record))
    lines = []
    for key in keys:
        values = [record.get(key, "-") for record in flat]
        if len(set(values)) > 1:
            said = ", ".join(f"#{n} {value}" for n, value in enumerate(values, 1))
            lines.append(f"`{key}`: {said}")
    if len(lines) > _MAX_DIFFERENCES:
        lines = [*lines[:_MAX_DIFFERENCES], f"... and {len(lines) - _MAX_DIFFERENCES} more"]
    return lines


def _flatten(record: dict[str, Any], prefix: str = "") -> dict[str, str]:
    """Nested dicts as dotted keys, every value as its JSON text."""
    flat: dict[str, str] = {}
    for key, value in record.items():
        if isinstance(value, dict) and value:
            flat.update(_flatten(value, f"{prefix}{key}."))
        else:
            flat[f"{prefix}{key}"] = json.dumps(value, sort_keys=True, default=str)
    return flat


def _markdown(
    out: Path,
    name: str,
    title: str,
    setup: str,
    entries: Sequence[OverlayRun],
    header: list[str],
    rows: list[list[str]],
    figures: Sequence[Path],
    problems: Sequence[str],
) -> str:
    differences = _differences(entries)
    lines = [
        f"# hil compare: {name}",
        "",
        f"{title}: {len(entries)} runs" + (f" on the {setup}" if setup else "") + ".",
        "",
        "## Metrics",
        "",
        markdown_table(header, rows),
        "",
        *(
            f"- #{n} {entry.label}: [`{_relative(out, entry.run.path)}/`]"
            f"({_relative(out, entry.run.path)})"
            for n, entry in enumerate(entries, 1)
        ),
        "",
        "## What differs between the runs' records (meta.json)",
        "",
        *([f"- {line}" for line in differences] or ["Nothing but when and where they ran."]),
        "",
        "## Figures",
        "",
        *([f"![{path.stem}]({_relative(out, path)})" for path in figures] or ["(no figures)"]),
        *([""] if problems else []),
        *(f"- note: {problem}" for problem in problems),
    ]
    return "\n".join(lines) + "\n"


def _relative(root: Path, path: Path) -> str:
    return os.path.relpath(path, root)
