"""results.csv: one row per finished run, appended (and synced) the moment the run is done.

Columns: run_id, point_id, the spec's parameters, experiment, controller, ending (the run's
Termination, or "failed" when it raised), ran_its_course, error, wall_time_s, out_dir, the
experiments' report metrics (one column each), and metrics_json (every metric, as JSON). A
rerun reads the file back and skips the run ids it holds; an interrupted write (a partial last
line) is dropped on reading, so that run is done again rather than lost.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from hil.output.strict_json import dumps
from hil.robots import EXPERIMENTS

RESULTS_NAME = "results.csv"
FIXED_HEAD = ("run_id", "point_id")
FIXED_TAIL = ("experiment", "controller", "ending", "ran_its_course", "error", "wall_time_s")
TRAILER = ("out_dir",)


class TableMismatch(ValueError):
    """results.csv in the output directory was written for another spec."""


def header(parameter_names: Sequence[str], experiments: Iterable[str]) -> list[str]:
    metric_keys: list[str] = []
    for name in experiments:
        for column in EXPERIMENTS[name].report_columns:
            if column.key not in metric_keys:
                metric_keys.append(column.key)
    return [*FIXED_HEAD, *parameter_names, *FIXED_TAIL, *TRAILER, *metric_keys, "metrics_json"]


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return "nan" if math.isnan(value) else repr(value)
    return str(value)


def _parse(text: str) -> Any:
    """A cell back to a value: numbers, booleans, empty as None, otherwise the text."""
    if text == "":
        return None
    if text in ("true", "false"):
        return text == "true"
    try:
        return float(text)
    except ValueError:
        return text


class ResultsTable:
    """results.csv of one sweep directory (see the module docstring)."""

    def __init__(self, out_dir: Path, columns: list[str]) -> None:
        self.path = Path(out_dir) / RESULTS_NAME
        self.columns = columns
        self.rows: dict[str, dict[str, Any]] = {}
        if self.path.is_file():
            self._read()
        else:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self.path.write_text(",".join(columns) + "\n")

    def _read(self) -> None:
        text = self.path.read_text()
        complete = text[: text.rfind("\n") + 1]  # a line cut by an interruption is not a row
        reader = csv.reader(io.StringIO(complete))
        found = next(reader, None)
        if found != self.columns:
            raise TableMismatch(
                f"{self.path} has the columns of another sweep ({found}); use another --out"
            )
        for cells in reader:
            if len(cells) != len(self.columns):
                continue
            row = {name: _parse(cell) for name, cell in zip(self.columns, cells, strict=True)}
            row["metrics"] = json.loads(str(row.pop("metrics_json") or "{}"))
            self.rows[str(row["run_id"])] = row
        if complete != text:
            self.path.write_text(complete)

    def __contains__(self, run_id: str) -> bool:
        return run_id in self.rows

    def append(self, row: dict[str, Any]) -> None:
        """Write one finished run's row now (flushed and synced: Ctrl-C loses none)."""
        metrics = row.get("metrics", {})
        values = {**metrics, **row, "metrics_json": dumps(metrics)}
        buffer = io.StringIO()
        csv.writer(buffer, lineterminator="\n").writerow(
            [_cell(values.get(name)) for name in self.columns]
        )
        with open(self.path, "a") as f:
            f.write(buffer.getvalue())
            f.flush()
            os.fsync(f.fileno())
        self.rows[str(row["run_id"])] = {**row, "metrics": metrics}
