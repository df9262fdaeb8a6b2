"""The run log: every signal at the loop rate, written as it happens so a crash loses nothing.

A run directory holds:
    meta.json     what ran: configuration, the hardware driven, controller, experiment, seed,
                  versions, start time
    log.csv       one row per tick (columns below), line-buffered: on disk when the row is done
                  (the loop writes a tick's row during the next tick, see hil/loop/run_record.py)
    events.jsonl  supervisor events (faults, safe states, exits), one JSON object per line
    summary.json  metrics and how the run ended (written at the end, even after an error)
    timing.csv    compute time per tick (kept out of log.csv, so lock-step logs are reproducible):
                  bus read (time in the bus's calls), controller + supervisor + write, and
                  (log_s) writing the previous tick's rows while this tick's answers travelled
    run.mcap      (unless turned off) every one of these as JSON channels for Foxglove and
                  PlotJuggler (hil/output/channels.py, hil/output/mcap_log.py)

Further message sinks (the live view, hil/output/live.py) get the same encoded messages.

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
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hil.output import channels as ch
from hil.output.channels import Channel, ChannelSet, MessageSink, encode_document
from hil.output.strict_json import dumps, plain
from hil.output.views import attach_views

MEASURED_JOINT_COLUMNS = (
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
)
# The controller's logged terms follow (`Controller.term_names`): the paper's controllers log
# the parts of the goal u = uc + d_hat + ug; a plug-in logs what it names, or nothing.
PAPER_TERM_COLUMNS = ("uc_rad", "d_hat_rad", "ug_rad")
PER_JOINT_COLUMNS = (*MEASURED_JOINT_COLUMNS, *PAPER_TERM_COLUMNS)  # the paper's controllers' log
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


def format_column(values: np.ndarray) -> list[str]:
    """`format_value` of every element of a per-joint array, in one pass per column (the log's
    hot path: ~200 cells a tick on the humanoid): the same text, cell for cell."""
    kind = values.dtype.kind
    if kind == "f":
        return [repr(round(value, 9)) for value in values.tolist()]
    if kind == "b":
        return ["1" if value else "0" for value in values.tolist()]
    if kind in "iu":
        return [str(value) for value in values.tolist()]
    return [format_value(value) for value in values]


_NOT_A_NUMBER = frozenset({"nan", "inf", "-inf"})


def _json_cells(column: str, cells: list[str]) -> list[str]:
    """A column's CSV cells as JSON values: flags true/false, NaN and infinity null."""
    if column in ch.BOOL_COLUMNS:
        return ["true" if cell == "1" else "false" for cell in cells]
    return ["null" if cell in _NOT_A_NUMBER else cell for cell in cells]


def _json_number(cell: str) -> str:
    """A numeric log cell as a JSON value: NaN and infinity null."""
    return "null" if cell in _NOT_A_NUMBER else cell


def _json_string(text: str) -> str:
    return json.dumps(text)


def per_joint_columns(term_columns: Sequence[str]) -> tuple[str, ...]:
    """A run's per-joint columns: the measured ones, then the controller's terms (refused if a
    term is named like a measured column)."""
    clash = sorted(set(term_columns) & set(MEASURED_JOINT_COLUMNS))
    if clash:
        raise ValueError(f"a controller's terms cannot be named {clash}: log.csv has them")
    return (*MEASURED_JOINT_COLUMNS, *term_columns)


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
        *,
        mcap: bool = False,
        sinks: Sequence[MessageSink] = (),
        term_columns: Sequence[str] = PAPER_TERM_COLUMNS,
    ) -> None:
        """mcap: also write run.mcap; sinks: more receivers of the messages (not closed here);
        term_columns: the controller's logged terms (per joint, after MEASURED_JOINT_COLUMNS)."""
        self.dir = Path(out_dir)
        self.per_joint_columns = per_joint_columns(term_columns)
        self.dir.mkdir(parents=True, exist_ok=True)
        self.joint_names = tuple(joint_names)
        self.sensor_columns = tuple(sensor_columns)
        n = len(self.joint_names)
        (self.dir / "meta.json").write_text(dumps(meta, indent=2) + "\n")
        joint_columns = [
            joint_column(c, name, n) for name in self.joint_names for c in self.per_joint_columns
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
        self._timing_file.write("tick,read_s,compute_s,write_s,cycle_s,log_s\n")
        self.rows = 0
        self.closed = False
        self._open_sinks(meta, mcap, sinks)

    # --- message sinks (run.mcap, the live view) ----------------------------------------------
    def _open_sinks(self, meta: dict[str, Any], mcap: bool, sinks: Sequence[MessageSink]) -> None:
        self.channels = ChannelSet(self.joint_names, self.per_joint_columns, self.sensor_columns)
        self.mcap = None
        if mcap:
            from hil.output.mcap_log import MCAP_NAME, McapSink

            self.mcap = McapSink(self.dir / MCAP_NAME)
        self._sinks: list[MessageSink] = [*([self.mcap] if self.mcap else []), *sinks]
        self._sinks, self._views = attach_views(self, meta, self._sinks)  # 3D view, ROS 2 bag
        for sink in self._sinks:
            for channel in self.channels.channels:
                sink.add_channel(channel)
        self._start_ns = time.time_ns()
        self._last_ns = self._start_ns
        self.publish(self.channels.meta, 0.0, encode_document(meta))
        if self.mcap is not None:
            self.mcap.metadata("run_meta", meta)

    def publish(self, channel: Channel, time_s: float, data: bytes) -> None:
        """One encoded message to every sink, at the run's time `time_s` (the hook for further
        channels, e.g. frame transforms: add them to `channels` before the first message)."""
        log_time_ns = self._start_ns + round(time_s * 1e9)
        self._last_ns = max(self._last_ns, log_time_ns)
        for sink in self._sinks:
            sink.message(channel.id, log_time_ns, data)

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
        `per_joint_columns` entry, each of length n_joints."""
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
        # joint-major: the cells of joint j are row[start + j * width : ... + width]
        start, width = self._joint_start, len(joints)
        end = start + width * len(self.joint_names)
        cells = [format_column(np.asarray(column)) for column in joints]
        for offset, column_cells in enumerate(cells):
            row[start + offset : end : width] = column_cells
        i = end
        row[i] = format_value(slack_s)
        row[i + 1] = format_value(measured_period_s)
        self._log.writerow(row)
        self.rows += 1
        if self._sinks:
            self.publish(self.channels.joints, time_s, self._joints_message(row, cells))
            self.publish(self.channels.loop, time_s, self._loop_message(row))

    def _joints_message(self, row: list[str], cells: list[list[str]]) -> bytes:
        """The /joints message from the row's own cells (the log's values, to 9 decimals):
        formatting ~180 numbers once, not again for JSON. A value not read is null."""
        arrays = ",".join(
            f'"{column}":[{",".join(_json_cells(column, column_cells))}]'
            for column, column_cells in zip(self.per_joint_columns, cells, strict=True)
        )
        return f'{{"tick":{row[0]},"time_s":{_json_number(row[1])},{arrays}}}'.encode()

    def _loop_message(self, row: list[str]) -> bytes:
        """The /loop message from the row's own cells, as /joints (the log's values)."""
        m = len(self.sensor_columns)
        sensors = "".join(
            f'"{name}":{_json_number(cell)},'
            for name, cell in zip(self.sensor_columns, row[2 : 2 + m], strict=True)
        )
        state, phase, skipped = row[2 + m : 5 + m]
        return (
            f'{{"tick":{row[0]},"time_s":{_json_number(row[1])},{sensors}'
            f'"supervisor_state":{_json_string(state)},"phase":{_json_string(phase)},'
            f'"skipped_ticks":{skipped},"slack_s":{_json_number(row[-2])},'
            f'"measured_period_s":{_json_number(row[-1])}}}'
        ).encode()

    def write_tick(self, row: tuple, timing: tuple) -> None:
        """One tick's rows: `write_row(*row)` and `write_timing(*timing)`."""
        self.write_row(*row)
        self.write_timing(*timing)

    def write_timing(
        self,
        tick: int,
        read_s: float,
        compute_s: float,
        write_s: float,
        log_s: float = math.nan,
        time_s: float = math.nan,
    ) -> None:
        """One tick's durations; log_s: writing the previous tick's rows during this tick's
        bus read (not part of read_s)."""
        cycle = read_s + compute_s + write_s
        cells = [f"{value:.7f}" for value in (read_s, compute_s, write_s, cycle, log_s)]
        self._timing_file.write(f"{tick},{','.join(cells)}\n")
        if self._sinks:  # the message from the row's cells (7 decimals), in TIMING_FIELDS order
            read, compute, write, cycle_cell, log = (_json_number(cell) for cell in cells)
            message = (
                f'{{"tick":{int(tick)},"read_s":{read},"compute_s":{compute},'
                f'"write_s":{write},"log_s":{log},"cycle_s":{cycle_cell}}}'
            )
            when = time_s if math.isfinite(time_s) else (self._last_ns - self._start_ns) / 1e9
            self.publish(self.channels.timing, when, message.encode())

    def event(self, time_s: float, kind: str, message: str, **fields: Any) -> None:
        record = {"time_s": round(time_s, 6), "kind": kind, "message": message, **fields}
        self._events_file.write(dumps(record) + "\n")
        if self._sinks:
            self.publish(self.channels.events, time_s, encode_document(record))

    def write_summary(self, summary: dict[str, Any]) -> None:
        """summary.json; then the summary is the last message: run.mcap is finished."""
        path = self.dir / "summary.json"
        tmp = path.with_suffix(".json.tmp")
        tmp.write_text(dumps(summary, indent=2) + "\n")
        tmp.replace(path)
        if self._sinks:
            self.publish(
                self.channels.summary, (self._last_ns - self._start_ns) / 1e9,
                encode_document(summary),
            )  # fmt: skip
        if self.mcap is not None:
            self.mcap.metadata("run_summary", plain(summary))
        self.finish_sinks()

    def finish_sinks(self) -> None:
        """run.mcap finished (its index written); later messages go to the CSV files only."""
        if self.mcap is not None:
            self.mcap.close()
        for view in self._views:
            view.close()
        self._sinks = []

    def close(self) -> None:
        """Close the CSV and JSON files (run.mcap stays open for the summary: `finish_sinks`)."""
        if self.closed:
            return
        self.closed = True
        for f in (self._log_file, self._events_file, self._timing_file):
            f.close()

    def __enter__(self) -> RunLog:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()
        self.finish_sinks()


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
