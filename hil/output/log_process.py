"""The run log written by a process of its own: the loop hands each tick's numbers over a pipe,
the log writer formats and writes them (log.csv, timing.csv, events.jsonl, run.mcap).

Formatting a humanoid tick's rows costs the loop ~0.3-0.4 ms (~200 cells to 9 decimals, the
MCAP messages); handing its ~220 numbers over costs ~25 us. In process the loop and the
emulated robot share one core and the writer takes the other; through the buses the loop and
the emulator alternate and the writer takes whichever core is free. The writer reads the pipe
every POLL_S (a reader waiting in read() would be woken by every row, and the kernel runs a task
woken through a pipe on the waker's CPU when it can) and runs at SCHED_BATCH (when it wakes it
does not preempt the loop).

    loop (`LogProcess`)                         writer (forked child, `_serve`)
    write_tick: the tick's numbers, one write   RunLog.write_row + write_timing, the same
                of fixed-size binary            text as a RunLog in the loop's process
    event, close, write_summary, finish_sinks   the same calls on its RunLog

Nothing is lost when either process ends unexpectedly:
- the loop ends (killed, crashed): the writer reads what the pipe holds to the end, closes
  log.csv, timing.csv and events.jsonl, and finishes run.mcap (its index written);
- the writer ends: the loop's next write fails with `LogWriterLost` (an OSError: the loop
  treats it as a lost bus, turns torque off and ends the run), and the summary is written by
  the loop's process itself.
The writer ignores Ctrl-C and SIGTERM (the loop handles them and closes the log in order).
Row ordering and content are the loop's; a lock-step log is the same bytes either way.

The live view (`hil run --live`) serves the messages from the loop's process: a run with
further message sinks keeps its RunLog there (`open_run_log`).
"""

from __future__ import annotations

import contextlib
import os
import pickle
import select
import signal
import struct
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hil.output import channels as ch
from hil.output.channels import MessageSink
from hil.output.runlog import PAPER_TERM_COLUMNS, RunLog, per_joint_columns
from hil.output.strict_json import dumps

_HEADER = struct.Struct("<II")  # record type, payload bytes
_ROW, _STRING, _EVENT, _CLOSE, _SUMMARY, _FINISH = range(1, 7)
_TIMING_VALUES = 6  # tick, read_s, compute_s, write_s, log_s, time_s
_ACK_TIMEOUT_S = 30.0  # the writer answers a close within this (it may have rows to write)
_PIPE_BYTES = 1 << 20  # ~600 humanoid ticks in flight before the loop would wait
POLL_S = 0.005  # the writer reads the pipe this often (it is never woken by the loop)
_F_SETPIPE_SZ = 1031  # fcntl on Linux


def never_preempt_the_loop() -> None:
    """This (helper) process at SCHED_BATCH where the OS has it: a batch task that wakes up
    does not take the CPU from the task running there (the loop); it runs on an idle CPU or
    when the loop waits. Any user may lower a process to it."""
    with contextlib.suppress(AttributeError, OSError):
        os.sched_setscheduler(0, os.SCHED_BATCH, os.sched_param(0))


class LogWriterLost(OSError):
    """The log writer process ended before the run did: the run stops as on a lost bus."""


def open_run_log(
    out_dir: Path,
    joint_names: Sequence[str],
    meta: dict[str, Any],
    sensor_columns: Sequence[str],
    *,
    mcap: bool,
    sinks: Sequence[MessageSink] = (),
    term_columns: Sequence[str] = PAPER_TERM_COLUMNS,
) -> RunLog | LogProcess:
    """The run's log: written by a process of its own, or in this one when there are further
    message sinks (the live view's server lives here) or no fork. term_columns: the
    controller's logged terms (`hil.output.runlog.per_joint_columns`)."""
    if sinks or not hasattr(os, "fork"):
        return RunLog(
            out_dir, joint_names, meta, sensor_columns, mcap=mcap, sinks=sinks,
            term_columns=term_columns,
        )  # fmt: skip
    return LogProcess(
        out_dir, joint_names, meta, sensor_columns, mcap=mcap, term_columns=term_columns
    )


class _RowLayout:
    """Where each number of a tick's record lies (float64 slots)."""

    def __init__(self, n_joints: int, n_sensors: int, columns: Sequence[str]) -> None:
        self.n = n_joints
        self.columns = tuple(columns)
        self.sensors = slice(2, 2 + n_sensors)
        self.state = 2 + n_sensors
        self.joints = self.state + 3  # state, phase, skipped
        self.clock = self.joints + len(self.columns) * n_joints
        self.timing = self.clock + 2
        self.size = self.timing + _TIMING_VALUES


class LogProcess:
    """The loop's side: the RunLog interface the loop uses, its work done by the writer."""

    def __init__(
        self,
        out_dir: Path,
        joint_names: Sequence[str],
        meta: dict[str, Any],
        sensor_columns: Sequence[str],
        *,
        mcap: bool,
        term_columns: Sequence[str] = PAPER_TERM_COLUMNS,
    ) -> None:
        self.dir = Path(out_dir)
        self.rows = 0
        self.closed = False
        columns = per_joint_columns(term_columns)
        self._layout = _RowLayout(len(joint_names), len(sensor_columns), columns)
        record = bytearray(_HEADER.size + 8 * self._layout.size)
        _HEADER.pack_into(record, 0, _ROW, 8 * self._layout.size)
        self._record = record
        self._row = np.frombuffer(memoryview(record)[_HEADER.size :], dtype=np.float64)
        self._strings: dict[str, int] = {}
        self._dead: str | None = None  # why the writer is gone
        self._finished = False
        rows_read, self._to_writer = os.pipe()
        self._acks, acks_written = os.pipe()
        with contextlib.suppress(OSError):  # a bigger pipe where the OS allows it
            import fcntl

            fcntl.fcntl(self._to_writer, _F_SETPIPE_SZ, _PIPE_BYTES)
        args = (out_dir, tuple(joint_names), meta, tuple(sensor_columns), mcap, tuple(term_columns))
        sys.stdout.flush()
        sys.stderr.flush()
        self.pid = os.fork()
        if self.pid == 0:  # the writer
            os.close(self._to_writer)
            os.close(self._acks)
            _serve(rows_read, acks_written, args, self._layout)  # never returns
        os.close(rows_read)
        os.close(acks_written)
        self._await("opening the run log")

    # --- per tick ------------------------------------------------------------------------
    def write_tick(self, row: tuple, timing: tuple) -> None:
        """One tick's log.csv row (`RunLog.write_row`'s arguments) and timing.csv row
        (`RunLog.write_timing`'s), in one write of ~8 bytes a number."""
        tick, time_s, sensors, state, phase, skipped, joints, slack_s, period_s = row
        layout, buffer = self._layout, self._row
        buffer[0] = tick
        buffer[1] = time_s
        buffer[layout.sensors] = sensors
        buffer[layout.state] = self._string_id(state)
        buffer[layout.state + 1] = self._string_id(phase)
        buffer[layout.state + 2] = skipped
        start, n = layout.joints, layout.n
        for column in joints:
            buffer[start : start + n] = column
            start += n
        buffer[layout.clock] = slack_s
        buffer[layout.clock + 1] = period_s
        buffer[layout.timing : layout.timing + len(timing)] = timing
        self._send(self._record)
        self.rows += 1

    def event(self, time_s: float, kind: str, message: str, **fields: Any) -> None:
        """One line of events.jsonl. Never raises: a writer that has ended is found by the
        next `write_tick` (events are also said on every exit path, which must go on)."""
        if self._dead is None and not self.closed:
            with contextlib.suppress(LogWriterLost):
                self._send_record(_EVENT, pickle.dumps((time_s, kind, message, fields)))

    # --- the end -------------------------------------------------------------------------
    def close(self) -> None:
        """log.csv, timing.csv and events.jsonl complete on disk (run.mcap stays open for the
        summary)."""
        if self.closed:
            return
        self.closed = True
        if self._dead is None:
            self._send_record(_CLOSE, b"")
            self._await("closing the log files")

    def write_summary(self, summary: dict[str, Any]) -> None:
        """summary.json, and run.mcap finished (the writer ends)."""
        if self._dead is None:
            with contextlib.suppress(LogWriterLost):
                self._send_record(_SUMMARY, pickle.dumps(summary))
                self._await("writing the summary")
                self._finished = True
        if self._dead is not None:  # the writer is gone: the summary is written from here
            path = self.dir / "summary.json"
            path.write_text(dumps(summary, indent=2) + "\n")
        self.finish_sinks()

    def finish_sinks(self) -> None:
        """The writer's end: everything written, run.mcap finished."""
        if self._dead is None and not self._finished:
            with contextlib.suppress(LogWriterLost):
                self._send_record(_FINISH, b"")
                self._await("finishing the log")
        self._finished = self.closed = True  # nothing more to write: close() does nothing
        self._reap()

    def __enter__(self) -> LogProcess:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()
        self.finish_sinks()

    # --- the pipe ------------------------------------------------------------------------
    def _string_id(self, text: str) -> int:
        number = self._strings.get(text)
        if number is None:
            number = self._strings[text] = len(self._strings)
            self._send_record(_STRING, text.encode())
        return number

    def _send_record(self, kind: int, payload: bytes) -> None:
        self._send(_HEADER.pack(kind, len(payload)) + payload)

    def _send(self, data: bytes | bytearray) -> None:
        if self._dead is not None:
            raise LogWriterLost(f"the log writer process has ended: {self._dead}")
        view = memoryview(data)
        try:
            while view:
                view = view[os.write(self._to_writer, view) :]
        except OSError as exc:
            self._lost(f"{type(exc).__name__}: {exc}")

    def _await(self, what: str) -> None:
        """The writer's answer to the last request ("ok", or why it failed)."""
        ready = select.select((self._acks,), (), (), _ACK_TIMEOUT_S)[0]
        answer = os.read(self._acks, 4096).decode(errors="replace") if ready else ""
        if answer.startswith("ok"):
            return
        self._lost(
            f"{what}: {answer.strip()}"
            if answer
            else f"{what}: no answer within {_ACK_TIMEOUT_S:g} s"
            if not ready
            else f"{what}: it ended"
        )

    def _lost(self, why: str) -> None:
        self._dead = why
        self._reap()
        raise LogWriterLost(f"the log writer process ended ({why}): the run stops")

    def _reap(self) -> None:
        for fd in (self._to_writer, self._acks):
            with contextlib.suppress(OSError):
                os.close(fd)
        self._to_writer = self._acks = -1
        if self.pid:
            with contextlib.suppress(ChildProcessError):
                os.waitpid(self.pid, 0)
            self.pid = 0


def _serve(rows: int, acks: int, args: tuple, layout: _RowLayout) -> None:
    """The writer: a RunLog fed from the pipe until FINISH or the loop's end of it closes."""
    code = 0
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        never_preempt_the_loop()
        out_dir, joint_names, meta, sensor_columns, mcap, terms = args
        log = RunLog(
            Path(out_dir), joint_names, meta, sensor_columns, mcap=mcap, term_columns=terms
        )
        os.write(acks, b"ok\n")
        _Writer(log, layout, acks).run(rows)
    except BaseException as exc:  # noqa: BLE001 - said to the loop, then the writer ends
        with contextlib.suppress(OSError):
            os.write(acks, f"{type(exc).__name__}: {exc}\n".encode())
        code = 1
    finally:
        os._exit(code)  # no atexit, no flush of the loop's buffers copied at the fork


class _Writer:
    """The writer's side of the pipe: records in, the RunLog's calls out."""

    def __init__(self, log: RunLog, layout: _RowLayout, acks: int) -> None:
        self.log = log
        self.layout = layout
        self.acks = acks
        self.strings: list[str] = []
        n, start = layout.n, layout.joints
        self.columns = []
        for c, name in enumerate(layout.columns):
            kind = bool if name in ch.BOOL_COLUMNS else int if name in ch.INTEGER_COLUMNS else None
            self.columns.append((slice(start + c * n, start + (c + 1) * n), kind))

    def run(self, rows: int) -> None:
        """Read what the pipe holds every POLL_S: a writer blocked in read() would be woken by
        every row the loop writes, and the kernel runs a task woken through a pipe on the
        waker's CPU when it can (the loop's), taking it from the loop each tick."""
        os.set_blocking(rows, False)
        pending = bytearray()
        while True:
            try:
                chunk = os.read(rows, _PIPE_BYTES)
            except BlockingIOError:
                time.sleep(POLL_S)
                continue
            if not chunk:  # the loop's process has ended: what was received is written
                self.log.close()
                self.log.finish_sinks()
                return
            pending += chunk
            offset = 0
            while len(pending) - offset >= _HEADER.size:
                kind, size = _HEADER.unpack_from(pending, offset)
                end = offset + _HEADER.size + size
                if end > len(pending):
                    break
                payload = bytes(pending[offset + _HEADER.size : end])
                offset = end
                if not self.handle(kind, payload):
                    return
            del pending[:offset]

    def handle(self, kind: int, payload: bytes) -> bool:
        """One record; False after the last."""
        log = self.log
        if kind == _ROW:
            self.row(np.frombuffer(payload, dtype=np.float64))
        elif kind == _STRING:
            self.strings.append(payload.decode())
        elif kind == _EVENT:
            time_s, event_kind, message, fields = pickle.loads(payload)
            log.event(time_s, event_kind, message, **fields)
        elif kind == _CLOSE:
            log.close()
            os.write(self.acks, b"ok\n")
        elif kind == _SUMMARY:
            log.write_summary(pickle.loads(payload))
            os.write(self.acks, b"ok\n")
        elif kind == _FINISH:
            log.close()
            log.finish_sinks()
            os.write(self.acks, b"ok\n")
            return False
        return True

    def row(self, values: np.ndarray) -> None:
        layout, strings = self.layout, self.strings
        joints = [
            values[where] if kind is None else values[where].astype(kind)
            for where, kind in self.columns
        ]
        timing = values[layout.timing : layout.timing + _TIMING_VALUES].tolist()
        clock = values[layout.clock : layout.clock + 2].tolist()
        self.log.write_row(
            int(values[0]),
            float(values[1]),
            values[layout.sensors].tolist(),
            strings[int(values[layout.state])],
            strings[int(values[layout.state + 1])],
            int(values[layout.state + 2]),
            joints,
            clock[0],
            clock[1],
        )
        tick, read_s, compute_s, write_s, log_s, time_s = timing
        self.log.write_timing(int(tick), read_s, compute_s, write_s, log_s, time_s)
