"""The run log: every signal at the loop rate, written as it happens so a crash loses nothing.

A run directory holds:
    meta.json     what ran: configuration, the hardware driven, controller, experiment, seed,
                  versions, start time
    log.csv       one row per tick (columns below), line-buffered: on disk when the row is done
    events.jsonl  supervisor events (faults, safe states, exits), one JSON object per line
    summary.json  metrics and how the run ended (written at the end, even after an error)
    timing.csv    compute time per tick (kept out of log.csv, so lock-step logs are reproducible)

Columns of log.csv: once per row `tick time_s <sensors> supervisor_state phase skipped_ticks`,
then per joint (suffix `[name]` when there is more than one joint) the PER_JOINT_COLUMNS, then
the clock columns `slack_s measured_period_s`. <sensors> are the robot's named scalar sensors
(the testbed: `contact_force_n`). actuator_fault holds `drivers.joint_bus.ActuatorFault` flags
(OVERLOAD = 1). In lock-step runs the clock columns hold the nominal period and no slack, so two
runs with the same seed write the same file byte for byte.

The per-tick path formats into preallocated lists: no dictionaries or arrays are built per row.
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
    "actuator_fault",
    "torque_enabled",
    "motor_valid",
    "link_valid",
    "link_age_s",
    "uc_rad",
    "d_hat_rad",
    "ug_rad",
)
DEFAULT_SENSOR_COLUMNS = ("contact_force_n",)
CLOCK_COLUMNS = ("slack_s", "measured_period_s")


def format_value(value: Any) -> str:
    """One cell: integers and flags as integers, floats to 9 decimals, NaN as 'nan'."""
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


def joint_column(name: str, joint: str, n_joints: int) -> str:
    """The header of a per-joint column: `name` for one joint, `name[joint]` for several."""
    return name if n_joints == 1 else f"{name}[{joint}]"


class RunLog:
    """Writes one run's directory. Use as a context manager; `close()` is safe twice."""

    def __init__(
        self,
        out_dir: Path,
        joint_names: Sequence[str],
        meta: dict[str, Any],
        sensor_columns: Sequence[str] = DEFAULT_SENSOR_COLUMNS,
    ) -> None:
        self.dir = Path(out_dir)
        self.dir.mkdir(parents=True, exist_ok=True)
        self.joint_names = tuple(joint_names)
        self.sensor_columns = tuple(sensor_columns)
        n = len(self.joint_names)
        (self.dir / "meta.json").write_text(json.dumps(meta, indent=2, default=str) + "\n")
        joint_columns = [
            joint_column(c, name, n) for name in self.joint_names for c in PER_JOINT_COLUMNS
        ]
        head = ["tick", "time_s", *self.sensor_columns, "supervisor_state", "phase"]
        self.columns = [*head, "skipped_ticks", *joint_columns, *CLOCK_COLUMNS]
        self._row: list[str] = [""] * len(self.columns)
        self._joint_start = len(head) + 1
        self._log_file = open(self.dir / "log.csv", "w", newline="", buffering=1)  # noqa: SIM115
        self._log = csv.writer(self._log_file, lineterminator="\n")
        self._log.writerow(self.columns)
        self._events_file = open(self.dir / "events.jsonl", "w", buffering=1)  # noqa: SIM115
        self._timing_file = open(self.dir / "timing.csv", "w", buffering=1)  # noqa: SIM115
        self._timing_file.write("tick,read_s,compute_s,write_s,cycle_s\n")
        self.rows = 0
        self.closed = False

    def write_row(
        self,
        tick: int,
        time_s: float,
        sensors: Sequence[float],
        supervisor_state: str,
        phase: str,
        skipped_ticks: int,
        joints: Sequence[np.ndarray],
        slack_s: float,
        measured_period_s: float,
    ) -> None:
        """One tick. `sensors` in `sensor_columns` order; `joints` one array per
        PER_JOINT_COLUMNS entry, each of length n_joints."""
        row = self._row
        row[0] = format_value(tick)
        row[1] = format_value(time_s)
        i = 2
        for value in sensors:
            row[i] = format_value(value)
            i += 1
        row[i] = supervisor_state
        row[i + 1] = phase
        row[i + 2] = format_value(skipped_ticks)
        i = self._joint_start
        for j in range(len(self.joint_names)):
            for column in joints:
                row[i] = format_value(column[j])
                i += 1
        row[i] = format_value(slack_s)
        row[i + 1] = format_value(measured_period_s)
        self._log.writerow(row)
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
        tmp.write_text(json.dumps(summary, indent=2, default=json_default) + "\n")
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


def json_default(value: Any) -> Any:
    """numpy values and anything else json cannot take, for json.dumps(default=...)."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    return str(value)


def read_log(path: Path) -> dict[str, np.ndarray]:
    """log.csv as columns of floats (supervisor_state and phase as strings)."""
    with open(path, newline="") as f:
        reader = csv.reader(f)
        header = next(reader)
        rows = list(reader)
    columns: dict[str, np.ndarray] = {}
    for i, name in enumerate(header):
        raw = [r[i] for r in rows]
        if name in ("supervisor_state", "phase"):
            columns[name] = np.array(raw, dtype=object)
        else:
            columns[name] = np.array([float(v) for v in raw])
    return columns
