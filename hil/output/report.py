"""The comparison report: several experiments, every controller, one page.

`write_report(root, entries, relations, figures, ...)` writes into `root` (the comparison
directory that holds one directory per run):
    report.md         setup, seed, package versions; the paper's relations, each checked
                      against our figures (holds / does not hold / not checked); the figures;
                      the metrics table; where each run's directory is
    report.json       the same as data (`Report.summary`, printed by `hil run --json`)
and returns a `Report` whose `table_text` is the terminal version.

The relations themselves are the experiments' (each experiment module checks the claims the
paper makes about it, from the runs' metrics, never hard-coded); this module gives them a common
shape (`Relation`, `check`, `metric`, `find`) and lays them out.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from hil.output.record_files import RecordWriteError
from hil.output.records import UNMEASURED, RunEntry
from hil.output.runlog import write_file_whole
from hil.output.strict_json import dumps
from hil.vocabulary import ControllerKind


@dataclass(frozen=True)
class Relation:
    """One of the paper's claims, with the paper's figures and ours, and whether it holds."""

    experiment: str
    claim: str
    paper: str
    ours: str
    holds: bool | None  # None: could not be checked (see note)
    note: str = ""

    @property
    def verdict(self) -> str:
        if self.holds is None:
            return "not checked"
        return "holds" if self.holds else "does not hold"


@dataclass(frozen=True)
class Report:
    table_text: str
    markdown_path: Path
    summary: dict[str, Any]
    relations: tuple[Relation, ...]
    figure_paths: tuple[Path, ...]
    not_written: str | None = None  # why report.md / report.json are not on disk (a full disk)

    @property
    def where(self) -> str:
        """Where the report is, or why it is not there, in one line."""
        if self.not_written is not None:
            return f"report not written: {self.not_written} (the table above is all of it)"
        return f"report: {self.markdown_path}"


# --- looking runs up and checking a claim --------------------------------------------------
class Missing(Exception):
    """A relation cannot be checked: the message says what is missing."""


def find(
    entries: Sequence[RunEntry],
    experiment: str,
    kind: ControllerKind,
    kdist: float | None = None,
    *,
    reading: str | None = None,
    gc_compliance: str | None = None,
) -> RunEntry | None:
    """The run of this experiment with this controller (and Kdist, and named reading of (25)
    and compliance of (8); None: the configuration's)."""
    for entry in entries:
        choice = entry.choice
        if entry.experiment != experiment or choice.kind is not kind:
            continue
        if choice.reading != reading or choice.gc_compliance != gc_compliance:
            continue
        if kdist is None or math.isclose(choice.kdist, kdist):
            return entry
    return None


def metric(entry: RunEntry | None, key: str, what: str) -> Any:
    """A run's metric, or Missing saying why the relation cannot use it."""
    if entry is None:
        raise Missing(f"no {what} run")
    result = entry.result
    if not result.termination.ran_its_course:
        raise Missing(f"the {what} run ended early: {result.ending}")
    if key not in result.metrics:
        error = result.metrics.get("error")
        raise Missing(f"the {what} run has no {key}" + (f" ({error})" if error else ""))
    why = (result.metrics.get(UNMEASURED) or {}).get(key)
    if result.metrics[key] is None and why:
        raise Missing(f"the {what} run did not measure {key}: {why}")
    return result.metrics[key]


def check(
    experiment: str, claim: str, paper: str, test: Callable[[], tuple[bool, str]], note: str = ""
) -> Relation:
    """Run `test` (-> holds, our figures); a Missing makes the relation 'not checked'."""
    try:
        holds, ours = test()
    except Missing as exc:
        return Relation(experiment, claim, paper, "-", None, str(exc))
    return Relation(experiment, claim, paper, ours, bool(holds), note)


def half_periods(count: int) -> str:
    return f"{count} half-period" + ("" if count == 1 else "s")


# --- the table --------------------------------------------------------------------------------
@dataclass(frozen=True)
class Column:
    """A metric shown in the runs table: its key, header and format."""

    key: str
    header: str
    fmt: Callable[[Any], str]


def number(digits: str) -> Callable[[Any], str]:
    def fmt(value: Any) -> str:
        if value is None:
            return "-"
        if isinstance(value, bool):
            return "yes" if value else "no"
        if isinstance(value, int | float):
            return format(value, digits)
        return str(value)

    return fmt


def _columns_for(entries: Sequence[RunEntry], known: Sequence[Column]) -> list[Column]:
    return metric_columns([entry.result.metrics for entry in entries], known)


def metric_columns(metrics: Sequence[Mapping[str, Any]], known: Sequence[Column]) -> list[Column]:
    """The known columns these runs' metrics have, then any other numeric metric (text, such
    as a note on why a figure is missing, stays in report.json)."""
    keys: list[str] = []
    for figures in metrics:
        keys += [
            k
            for k, v in figures.items()
            if k not in keys and (v is None or isinstance(v, int | float))
        ]
    by_key = {c.key: c for c in known}
    ordered = [c for c in known if c.key in keys]
    return ordered + [Column(k, k, number(".4g")) for k in keys if k not in by_key]


def _ended(entry: RunEntry) -> str:
    result = entry.result
    if result.safety_events and not result.ok:
        return f"{result.ending} at {result.safety_events[0].time_s:.3f} s"
    return str(result.ending)


def _table_rows(
    entries: Sequence[RunEntry], known: Sequence[Column]
) -> tuple[list[str], list[list[str]]]:
    columns = _columns_for(entries, known)
    header = ["experiment", "controller", *(c.header for c in columns), "ended"]
    rows = [
        [
            entry.experiment,
            entry.choice.label,
            *(c.fmt(entry.result.metrics.get(c.key)) for c in columns),
            _ended(entry),
        ]
        for entry in entries
    ]
    return header, rows


def _by_experiment(entries: Sequence[RunEntry]) -> dict[str, list[RunEntry]]:
    grouped: dict[str, list[RunEntry]] = {}
    for entry in entries:
        grouped.setdefault(entry.experiment, []).append(entry)
    return grouped


def plain_table(header: list[str], rows: list[list[str]]) -> str:
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
    numeric = [all(_looks_numeric(r[i]) for r in rows) and i > 1 for i in range(len(header))]

    def line(cells: list[str]) -> str:
        return "  ".join(
            c.rjust(w) if right else c.ljust(w)
            for c, w, right in zip(cells, widths, numeric, strict=True)
        ).rstrip()

    return "\n".join([line(header), line(["-" * w for w in widths]), *map(line, rows)])


def _looks_numeric(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return text == "-"
    return True


def markdown_table(header: list[str], rows: list[list[str]]) -> str:
    def line(cells: list[str]) -> str:
        return "| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |"

    return "\n".join([line(header), "|" + "---|" * len(header), *map(line, rows)])


# --- where it came from -----------------------------------------------------------------------
def _provenance(entries: Sequence[RunEntry]) -> dict[str, Any]:
    """Seed(s), controller settings, Python and package versions from the runs' meta.json."""
    seeds: list[Any] = []
    packages: dict[str, str] = {}
    python = ""
    config: dict[str, Any] = {}
    for entry in entries:
        meta_path = Path(entry.result.out_dir) / "meta.json"
        try:
            meta = json.loads(meta_path.read_text())
        except (OSError, ValueError):  # none, or not whole (a run that never began)
            continue
        if meta.get("seed") not in seeds:
            seeds.append(meta.get("seed"))
        packages = packages or dict(meta.get("packages", {}))
        python = python or str(meta.get("python", ""))
        config = config or dict(meta.get("config", {}))
    controller = config.get("controller", {})
    safety = config.get("safety", {})
    return {
        "seed": seeds[0] if len(seeds) == 1 else (seeds or None),
        "python": python or None,
        "packages": packages,
        "config_source": config.get("source"),
        "composition": controller.get("composition"),
        "current_guard": safety.get("current_guard"),
    }


def _where(root: Path, out_dir: Path) -> str:
    try:
        return str(Path(out_dir).relative_to(root))
    except ValueError:
        return str(out_dir)


# --- the report -------------------------------------------------------------------------------
@dataclass(frozen=True)
class ReportContent:
    """What goes into a report besides the runs: title, the claims' source, setup, timing."""

    title: str
    claims_source: str  # e.g. "Kim et al., ICRA 2018, Sec. IV-B"
    setup: str
    wall_time_s: float
    columns: tuple[Column, ...] = ()


def write_report(
    root: Path,
    entries: Sequence[RunEntry],
    relations: Sequence[Relation],
    figures: Sequence[Path],
    figure_problems: Sequence[str],
    content: ReportContent,
) -> Report:
    """Write report.md and report.json into `root`; see the module docstring."""
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    provenance = _provenance(entries)
    tables = {
        name: _table_rows(group, content.columns) for name, group in _by_experiment(entries).items()
    }
    counts = {
        verdict: sum(r.verdict == verdict for r in relations)
        for verdict in ("holds", "does not hold", "not checked")
    }
    table_text = _terminal_text(content, provenance, tables, relations, counts)
    markdown_path = root / "report.md"
    markdown = _markdown(
        root, entries, content, provenance, tables, relations, counts, figures, figure_problems
    )
    summary = {
        "setup": content.setup,
        **provenance,
        "wall_time_s": content.wall_time_s,
        "root": str(root),
        "report": str(markdown_path),
        "figures": [str(p) for p in figures],
        "runs": [
            {
                "experiment": entry.experiment,
                "controller": entry.choice.name,
                "kdist": entry.choice.kdist if entry.choice.uses_kdist else None,
                "reading": entry.choice.reading,
                "label": entry.choice.label,
                "termination": str(entry.result.ending),
                "out_dir": str(entry.result.out_dir),
                "metrics": entry.result.metrics,
            }
            for entry in entries
        ],
        "relations": [{**asdict(r), "verdict": r.verdict} for r in relations],
        "relation_counts": counts,
    }
    not_written = None
    for path, text in ((markdown_path, markdown), (root / "report.json", dumps(summary, indent=2))):
        try:
            write_file_whole(path, text if text.endswith("\n") else text + "\n")
        except RecordWriteError as exc:  # a full disk: the report is still printed
            not_written = not_written or str(exc)
    if not_written is not None:
        summary["report"] = None
    return Report(table_text, markdown_path, summary, tuple(relations), tuple(figures), not_written)


def _on_off(flag: bool | None) -> str:
    return "unknown" if flag is None else ("on" if flag else "off")


def _counts_line(counts: dict[str, int]) -> str:
    holds = "hold" if counts["holds"] != 1 else "holds"
    fails = "do not hold" if counts["does not hold"] != 1 else "does not hold"
    return (
        f"{counts['holds']} {holds}, {counts['does not hold']} {fails}, "
        f"{counts['not checked']} not checked"
    )


def _terminal_text(
    content: ReportContent,
    provenance: dict[str, Any],
    tables: dict[str, tuple[list[str], list[list[str]]]],
    relations: Sequence[Relation],
    counts: dict[str, int],
) -> str:
    lines = [
        f"Comparison on the {content.setup} (seed {provenance['seed']}, reading of (25): "
        f"{provenance['composition'] or 'unknown'}, software current guard "
        f"{_on_off(provenance['current_guard'])}, {content.wall_time_s:.1f} s)",
        "",
    ]
    for header, rows in tables.values():
        lines += [plain_table(header, rows), ""]
    lines.append(f"The paper's relations ({content.claims_source}): {_counts_line(counts)}")
    for r in relations:
        detail = f"ours {r.ours}; paper {r.paper}"
        if r.holds is None:
            detail = r.note
        lines.append(f"  [{r.verdict:^13}] {r.experiment}: {r.claim}: {detail}")
    return "\n".join(lines)


def _markdown(
    root: Path,
    entries: Sequence[RunEntry],
    content: ReportContent,
    provenance: dict[str, Any],
    tables: dict[str, tuple[list[str], list[list[str]]]],
    relations: Sequence[Relation],
    counts: dict[str, int],
    figures: Sequence[Path],
    figure_problems: Sequence[str],
) -> str:
    packages = ", ".join(f"{k} {v}" for k, v in provenance["packages"].items()) or "unknown"
    out = [
        f"# {content.title}",
        "",
        f"- setup: {content.setup}",
        f"- seed: {provenance['seed']}",
        f"- configuration: {provenance['config_source'] or 'unknown'}; reading of (25): "
        f"{provenance['composition'] or 'unknown'}; software current guard: "
        f"{_on_off(provenance['current_guard'])}",
        f"- runs: {len(entries)} in {content.wall_time_s:.1f} s",
        f"- python {provenance['python'] or 'unknown'}; packages: {packages}",
        "",
        "## The paper's relations",
        "",
        f"Checked from the runs' metrics ({_counts_line(counts)}).",
        "",
        markdown_table(
            ["experiment", "relation", "paper", "ours", "verdict", "criterion / note"],
            [
                [r.experiment, r.claim, r.paper, r.ours, f"**{r.verdict}**", r.note]
                for r in relations
            ],
        ),
        "",
        "## Figures",
        "",
    ]
    out += [f"![{p.stem}]({_where(root, p)})" for p in figures] or ["(no figures)"]
    out += [f"- figure problem: {problem}" for problem in figure_problems]
    out += ["", "## Runs", ""]
    for header, rows in tables.values():
        out += [markdown_table(header, rows), ""]
    out += ["## Run directories", ""]
    for entry in entries:
        out.append(f"- {entry.experiment} / {entry.choice.label}: {_run_files(root, entry)}")
    return "\n".join(out) + "\n"


def _run_files(root: Path, entry: RunEntry) -> str:
    """A run's directory and the files it holds (a run whose worker was killed may have no
    summary.json: it is said missing, not listed)."""
    out_dir = Path(entry.result.out_dir)
    where = _where(root, out_dir)
    files = [name for name in _RUN_FILES if (out_dir / name).is_file()]
    files += [
        f"[{p.name}]({where}/{p.name})" for p in sorted(out_dir.glob("plot*.png")) if p.is_file()
    ]
    missing = [name for name in _RUN_FILES if not (out_dir / name).is_file()]
    listed = f"({', '.join(files)})" if files else "(no files)"
    said = f"; no {', '.join(missing)}" if missing else ""
    return f"`{where}/` {listed}{said}"


_RUN_FILES = ("log.csv", "events.jsonl", "summary.json")
