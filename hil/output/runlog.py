"""The run log: every signal at the loop rate, written as it happens so a crash loses nothing.

A run directory holds:
    meta.json     what ran: configuration, the hardware driven, controller, experiment, seed,
                  versions, start time
    log.csv       one row per tick (columns below), each on disk when it is done (the loop
                  writes a tick's row during the next tick, see hil/loop/run_record.py)
    events.jsonl  supervisor events (faults, safe states, exits), one JSON object per line
    summary.json  metrics and how the run ended (written at the end, even after an error);
                  `record` says whether the record is whole (`record_report`)
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

A line is written whole or not at all (hil/output/record_files.py): when the disk is full,
the row or event that did not fit is cut off again, `write_row` raises `RecordWriteError` (the
loop stops the run as on a lost bus), the room kept for the record's end is given back, the
rows after it are counted, not written, and the exit path's events and summary.json still go
in. `RunLog(..., resume=sizes)` takes over files another process wrote (the log writer's,
hil/output/log_process.py): cut to the sizes it reported, no header written again.

The per-tick path formats into preallocated lists: no dictionaries or arrays are built per row.
"""

from __future__ import annotations

import csv
import enum
import json
import math
import os
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from hil.output import channels as ch
from hil.output.channels import Channel, ChannelSet, MessageSink, encode_document
from hil.output.record_files import DiskReserve, RecordFile, RecordWriteError
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


class FileSizes(NamedTuple):
    """How many bytes of log.csv, events.jsonl and timing.csv are whole on disk."""

    log: int
    events: int
    timing: int


class RecordState(enum.StrEnum):
    """Whether a run's record is whole (summary.json `record.state`)."""

    COMPLETE = "complete"  # every row and event on disk, as written
    WRITTEN_BY_LOOP = "written by the loop"  # the log writer was lost; the loop wrote the rest
    INCOMPLETE = "incomplete"  # rows or events could not be written (the disk was full)


RECORD_INCOMPLETE = "record incomplete"  # how an exit note about a record not whole begins


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
        resume: FileSizes | None = None,
    ) -> None:
        """mcap: also write run.mcap; sinks: more receivers of the messages (not closed here);
        term_columns: the controller's logged terms (per joint, after MEASURED_JOINT_COLUMNS);
        resume: go on with the files another process wrote, at these sizes (meta and mcap
        are not written)."""
        self.dir = Path(out_dir)
        self.per_joint_columns = per_joint_columns(term_columns)
        self.dir.mkdir(parents=True, exist_ok=True)
        self.joint_names = tuple(joint_names)
        self.sensor_columns = tuple(sensor_columns)
        n = len(self.joint_names)
        joint_columns = [
            joint_column(c, name, n) for name in self.joint_names for c in self.per_joint_columns
        ]
        head = ["tick", "time_s", *self.sensor_columns, "supervisor_state", "phase"]
        self.columns = [*head, "skipped_ticks", *joint_columns, *CLOCK_COLUMNS]
        self._row: list[str] = [""] * len(self.columns)
        self._joint_start = len(head) + 1
        self.rows = 0
        self.closed = False
        self.write_error: RecordWriteError | None = None  # the first write the disk refused
        self._error_raised = False  # write_row has raised it (the loop knows)
        self.rows_not_written = 0
        self.events_not_written = 0
        self.reserve = DiskReserve(self.dir, create=resume is None)
        if resume is None:
            write_file_whole(self.dir / "meta.json", dumps(meta, indent=2) + "\n")
        self._log_file = RecordFile(self.dir / "log.csv", resume_at=resume and resume.log)
        self._log = csv.writer(self._log_file, lineterminator="\n")
        self._events_file = RecordFile(
            self.dir / "events.jsonl", resume_at=resume and resume.events
        )
        self._timing_file = RecordFile(self.dir / "timing.csv", resume_at=resume and resume.timing)
        if resume is None:
            self._log.writerow(self.columns)
            self._timing_file.write("tick,read_s,compute_s,write_s,cycle_s,log_s\n")
        self._open_sinks(meta, mcap and resume is None, sinks, views=resume is None)

    # --- message sinks (run.mcap, the live view) ----------------------------------------------
    def _open_sinks(
        self, meta: dict[str, Any], mcap: bool, sinks: Sequence[MessageSink], *, views: bool
    ) -> None:
        """views: the 3D view and ROS 2 bag too (not when going on with another process's
        files: its bag is its own, and left as it wrote it)."""
        self.channels = ChannelSet(self.joint_names, self.per_joint_columns, self.sensor_columns)
        self.mcap = None
        if mcap:
            from hil.output.mcap_log import MCAP_NAME, McapSink

            self.mcap = McapSink(self.dir / MCAP_NAME)
        self._sinks: list[MessageSink] = [*([self.mcap] if self.mcap else []), *sinks]
        self._views: list[MessageSink] = []
        if views:
            self._sinks, self._views = attach_views(self, meta, self._sinks)
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
        `per_joint_columns` entry, each of length n_joints. Raises RecordWriteError when a
        write failed (this row's, or an event's since): once; later rows are counted, not
        written (see the module docstring)."""
        if self.write_error is not None:
            self.rows_not_written += 1
            self._raise_once()
            return
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
        try:
            self._log.writerow(row)
            self.rows += 1
            if self._sinks:
                self.publish(self.channels.joints, time_s, self._joints_message(row, cells))
                self.publish(self.channels.loop, time_s, self._loop_message(row))
        except RecordWriteError as exc:
            self._failed(exc)
            self._raise_once()

    # --- a write the disk refused ----------------------------------------------------------
    def _failed(self, exc: RecordWriteError) -> None:
        """The first failed write: remembered, the reserve given back for the record's end."""
        if self.write_error is None:
            self.write_error = exc
            self.reserve.release()

    def _raise_once(self) -> None:
        if self.write_error is not None and not self._error_raised:
            self._error_raised = True
            raise self.write_error

    def sizes(self) -> FileSizes:
        """What is whole on disk of the three text files."""
        return FileSizes(self._log_file.size, self._events_file.size, self._timing_file.size)

    def record_report(self) -> dict[str, Any]:
        """summary.json's `record`: whether every row and event is on disk."""
        whole = self.write_error is None
        report: dict[str, Any] = {
            "state": str(RecordState.COMPLETE if whole else RecordState.INCOMPLETE),
            "rows": self.rows + self.rows_not_written,  # the run's, as the loop handed them
        }
        if not whole:
            report.update(
                problem=str(self.write_error),
                rows_not_written=self.rows_not_written,
                events_not_written=self.events_not_written,
            )
        return report

    def record_note(self) -> str | None:
        """One line for the exit notes when the record is not whole (None: it is)."""
        if self.write_error is None:
            return None
        return (
            f"{RECORD_INCOMPLETE}: {self.write_error}; {self.rows} rows whole on disk, "
            f"{self.rows_not_written} not written"
        )

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
        if self.write_error is not None:  # the row's write_row said so
            return
        cycle = read_s + compute_s + write_s
        cells = [f"{value:.7f}" for value in (read_s, compute_s, write_s, cycle, log_s)]
        try:
            self._timing_file.write(f"{tick},{','.join(cells)}\n")
        except RecordWriteError as exc:
            self._failed(exc)
            self._raise_once()
            return
        if self._sinks:  # the message from the row's cells (7 decimals), in TIMING_FIELDS order
            read, compute, write, cycle_cell, log = (_json_number(cell) for cell in cells)
            message = (
                f'{{"tick":{int(tick)},"read_s":{read},"compute_s":{compute},'
                f'"write_s":{write},"log_s":{log},"cycle_s":{cycle_cell}}}'
            )
            when = time_s if math.isfinite(time_s) else (self._last_ns - self._start_ns) / 1e9
            try:
                self.publish(self.channels.timing, when, message.encode())
            except RecordWriteError as exc:
                self._failed(exc)
                self._raise_once()

    def event(self, time_s: float, kind: str, message: str, **fields: Any) -> None:
        """One line of events.jsonl. Never raises (events are said on every exit path, which
        must go on): a failed write is remembered, and the next `write_row` raises it."""
        if self.closed:
            self.events_not_written += 1
            return
        record = {"time_s": round(time_s, 6), "kind": kind, "message": message, **fields}
        try:
            self._events_file.write(dumps(record) + "\n")
            if self._sinks:
                self.publish(self.channels.events, time_s, encode_document(record))
        except RecordWriteError as exc:
            self.events_not_written += 1
            self._failed(exc)

    def write_summary(self, summary: dict[str, Any]) -> None:
        """summary.json, with `record` (`record_report`); then the summary is the last message:
        run.mcap is finished. Raises RecordWriteError if summary.json could not be written
        (the sinks are finished all the same)."""
        summary = {**summary, "record": self.record_report()}
        try:
            write_summary_file(self.dir, summary)
            if self._sinks:
                self.publish(
                    self.channels.summary, (self._last_ns - self._start_ns) / 1e9,
                    encode_document(summary),
                )  # fmt: skip
            if self.mcap is not None:
                self.mcap.metadata("run_summary", plain(summary))
        except RecordWriteError as exc:
            self._failed(exc)
            raise
        finally:
            self.finish_sinks()

    def finish_sinks(self) -> None:
        """run.mcap finished (its index written; left as it is if a write of it failed), the
        views (the ROS 2 bag) finished, the reserve removed; later messages go to the CSV
        files only."""
        self._sinks = []
        try:
            if self.mcap is not None:
                self.mcap.close()
        except RecordWriteError as exc:
            self._failed(exc)
        finally:
            for view in self._views:
                view.close()  # never raises: a view's failure is said, never the run's
            self.reserve.release()

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


def write_summary_file(out_dir: Path, summary: dict[str, Any]) -> None:
    """summary.json, atomically (a reader never sees half of it); RecordWriteError if the disk
    did not take it (nothing is left half-written)."""
    write_file_whole(Path(out_dir) / "summary.json", dumps(summary, indent=2) + "\n")


def write_file_whole(path: Path, text: str) -> None:
    """A small file atomically: whole or not there (RecordWriteError)."""
    tmp = path.with_name(f".{path.name}.tmp")
    try:
        tmp.write_text(text)
        tmp.replace(path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise RecordWriteError(path, exc) from exc


TORN_LAST_ROW = (
    "its last row is torn (the file ends in the middle of it: the disk was full or its writer "
    "was killed while writing it): read without it"
)


def read_log(path: Path) -> dict[str, np.ndarray]:
    """log.csv as columns of floats (supervisor_state and phase as strings); a torn last row
    is left out (`read_log_checked` says so)."""
    return read_log_checked(path)[0]


def read_log_checked(path: Path) -> tuple[dict[str, np.ndarray], str | None]:
    """log.csv as `read_log` reads it, and a note when its last row was torn and left out.
    A row torn elsewhere (not the last) is a damaged log: ValueError naming the line."""
    path = Path(path)
    with open(path, "rb") as f:  # a file that does not end with a newline ends mid-row
        size = f.seek(0, os.SEEK_END)
        whole = size == 0 or (f.seek(size - 1) >= 0 and f.read(1) == b"\n")
    with open(path, newline="") as f:
        reader = csv.reader(f)
        header = next(reader, None)
        if header is None:
            raise ValueError(f"{path} is empty: not a hil run log")
        rows = list(reader)
    note = None
    if rows and (not whole or len(rows[-1]) != len(header)):
        rows.pop()
        note = f"{path}: {TORN_LAST_ROW}"
    for number, row in enumerate(rows, start=2):
        if len(row) != len(header):
            raise ValueError(
                f"{path}: line {number} has {len(row)} cells, the header {len(header)}: "
                "the log is damaged"
            )
    columns: dict[str, np.ndarray] = {}
    for i, name in enumerate(header):
        raw = [r[i] for r in rows]
        if name in ("supervisor_state", "phase"):
            columns[name] = np.array(raw, dtype=object)
        else:
            columns[name] = np.array([float(v) for v in raw])
    return columns, note
