"""The run log: every signal at the loop rate, written as it happens so a crash loses nothing.

A run directory holds:
    meta.json     what ran: configuration, controller, experiment, seed, versions, start time
    log.csv       one row per tick (columns below), line-buffered: on disk when the row is done
    events.jsonl  supervisor events (faults, safe states, exits), one JSON object per line
    summary.json  metrics and the termination reason (written at the end, even after an error)

Columns of log.csv, per joint (suffix `[name]` when there is more than one joint):
    reference_rad goal_rad motor_angle_rad link_angle_rad deflection_rad motor_velocity_rad_s
    motor_current_a hardware_error torque_enabled motor_valid link_valid link_age_s
    uc_rad d_hat_rad ug_rad
and once per row: tick time_s contact_force_n supervisor_state skipped_ticks slack_s
measured_period_s. In lock-step runs the clock columns hold the nominal period and no slack, so
two runs with the same seed write the same file byte for byte; compute times go to timing.csv.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

PER_JOINT_COLUMNS = (
    "reference_rad",
    "goal_rad",
    "motor_angle_rad",
    "link_angle_rad",
    "deflection_rad",
    "motor_velocity_rad_s",
    "motor_current_a",
    "hardware_error",
    "torque_enabled",
    "motor_valid",
    "link_valid",
    "link_age_s",
    "uc_rad",
    "d_hat_rad",
    "ug_rad",
)
ROW_COLUMNS = ("tick", "time_s", "contact_force_n", "supervisor_state", "skipped_ticks")
CLOCK_COLUMNS = ("slack_s", "measured_period_s")


def _fmt(value: Any) -> str:
    if isinstance(value, bool | np.bool_):
        return "1" if value else "0"
    if isinstance(value, int | np.integer):
        return str(int(value))
    if isinstance(value, float | np.floating):
        value = float(value)
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(round(value, 9))
    return str(value)


class RunLog:
    """Writes one run's directory. Use as a context manager; `close()` is safe twice."""

    def __init__(self, out_dir: Path, joint_names: Sequence[str], meta: dict[str, Any]) -> None:
        self.dir = Path(out_dir)
        self.dir.mkdir(parents=True, exist_ok=True)
        self.joint_names = tuple(joint_names)
        (self.dir / "meta.json").write_text(json.dumps(meta, indent=2, default=str) + "\n")
        if len(self.joint_names) == 1:
            joint_columns = list(PER_JOINT_COLUMNS)
        else:
            joint_columns = [f"{c}[{n}]" for n in self.joint_names for c in PER_JOINT_COLUMNS]
        self.columns = [*ROW_COLUMNS, *joint_columns, *CLOCK_COLUMNS]
        self._log_file = open(self.dir / "log.csv", "w", newline="", buffering=1)  # noqa: SIM115
        self._log = csv.writer(self._log_file, lineterminator="\n")
        self._log.writerow(self.columns)
        self._events_file = open(self.dir / "events.jsonl", "w", buffering=1)  # noqa: SIM115
        self._timing_file = open(self.dir / "timing.csv", "w", buffering=1)  # noqa: SIM115
        self._timing_file.write("tick,read_s,compute_s,write_s,cycle_s\n")
        self.rows = 0
        self.closed = False

    def write_row(self, row: dict[str, Any], joints: dict[str, np.ndarray]) -> None:
        """row: the ROW_COLUMNS and CLOCK_COLUMNS values; joints: PER_JOINT_COLUMNS arrays."""
        values = [_fmt(row[c]) for c in ROW_COLUMNS]
        n = len(self.joint_names)
        if n == 1:
            values += [_fmt(joints[c][0]) for c in PER_JOINT_COLUMNS]
        else:
            values += [_fmt(joints[c][i]) for i in range(n) for c in PER_JOINT_COLUMNS]
        values += [_fmt(row[c]) for c in CLOCK_COLUMNS]
        self._log.writerow(values)
        self.rows += 1

    def write_timing(self, tick: int, read_s: float, compute_s: float, write_s: float) -> None:
        cycle = read_s + compute_s + write_s
        self._timing_file.write(f"{tick},{read_s:.7f},{compute_s:.7f},{write_s:.7f},{cycle:.7f}\n")

    def event(self, time_s: float, kind: str, message: str, **fields: Any) -> None:
        record = {"time_s": round(time_s, 6), "kind": kind, "message": message, **fields}
        self._events_file.write(json.dumps(record, default=str) + "\n")

    def write_summary(self, summary: dict[str, Any]) -> None:
        path = self.dir / "summary.json"
        tmp = path.with_suffix(".json.tmp")
        tmp.write_text(json.dumps(summary, indent=2, default=_json_default) + "\n")
        tmp.replace(path)

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        for f in (self._log_file, self._events_file, self._timing_file):
            f.close()

    def __enter__(self) -> RunLog:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    return str(value)


def read_log(path: Path) -> dict[str, np.ndarray]:
    """log.csv as columns of floats (supervisor_state as strings)."""
    with open(path, newline="") as f:
        reader = csv.reader(f)
        header = next(reader)
        rows = list(reader)
    columns: dict[str, np.ndarray] = {}
    for i, name in enumerate(header):
        raw = [r[i] for r in rows]
        if name == "supervisor_state":
            columns[name] = np.array(raw, dtype=object)
        else:
            columns[name] = np.array([float(v) for v in raw])
    return columns
