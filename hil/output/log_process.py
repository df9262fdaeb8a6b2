"""The run log written by a process of its own: the loop hands each tick's numbers over a pipe,
the log writer formats and writes them (log.csv, timing.csv, events.jsonl, run.mcap).

Formatting a humanoid tick's rows costs the loop ~0.3-0.4 ms (~200 cells to 9 decimals, the
MCAP messages); handing its ~220 numbers over costs ~25 us. In process the loop and the
emulated robot share one core and the writer takes the other; through the buses the loop and
the emulator alternate and the writer takes whichever core is free. The writer reads the pipe
every POLL_S (a reader waiting in read() would be woken by every row, and the kernel runs a task
woken through a pipe on the waker's CPU when it can) and runs at SCHED_BATCH (when it wakes it
does not preempt the loop). It is named hil-log-writer (ps -o comm, top).

    loop (`LogProcess`)                         writer (forked child, `_serve`)
    write_tick: the tick's numbers, one record  RunLog.write_row + write_timing, the same
                of fixed-size binary            text as a RunLog in the loop's process
    event, close, write_summary, finish_sinks   the same calls on its RunLog

No hand-over waits for the writer. The pipe is written without blocking; what it does not take
waits in the loop's process (at most BACKLOG_BYTES) and goes on at the next hand-over. The loop
keeps every record until the writer says it has handled it (hil/output/writer_watch.py: the
writer counts its records, with how many bytes of each file are whole, in memory the two
share), and judges the writer by that progress: one that stalls - no record handled for
WRITER_STALL_S while it had some, and then neither running nor waiting for a CPU
(stopped, or stuck on a disk that does not answer) - is found within ~0.6 s, whatever the
pipe holds. Every wait for an answer (opening, closing, the summary) is bounded the same way,
and a writer that was killed is waited for at most REAP_S, never in a blocking waitpid.

A writer that stalls, ends, or falls BACKLOG_BYTES behind is lost:
- it is killed (SIGKILL: a stopped process too), and the record says so in events.jsonl, at its
  place among the other events (kind `log_writer_stalled` or `log_writer_lost`: the writer's
  process, its state, the tick and time of the loop's last row, how many records it owed), in
  summary.json's `record` (state `written by the loop`, `writer`, rows by each) and in the exit
  notes ('record: the log writer (process N) has stalled: ..., at tick K; the loop wrote the
  rest');
- the next `write_tick` raises `LogWriterStalled` / `LogWriterLost` (OSErrors): the loop stops
  the run as on a lost bus, torque off (the configured exit state) on its exit path;
- after the exit path (at `close`, or `write_summary`), the loop writes the record itself: it
  cuts log.csv, events.jsonl and timing.csv to the sizes the writer last said were whole (a
  row it was writing when it stopped goes, never half of it) and appends every record the
  writer had not handled - the rows, the events of the end, summary.json - from a RunLog of
  its own (`RunLog(resume=...)`). run.mcap stays as the writer left it, without its index
  (`mcap recover` rebuilds it; log.csv is the record). Nothing is written to disk between the
  loss and the exit path: a disk that hangs cannot keep torque on.
A writer that stalls only at the end (the close, the summary) ends a run that completed: the
loop writes the rest, the run still completed, and the record says what stalled and when.

A write of the record that fails (the disk is full: hil/output/record_files.py) ends the writer
with the file whole to its last line; the loop stops the run as for a lost writer (kind
`record_write_failed`, the message naming the file), and at its end writes the events of the
exit path and summary.json into the room kept for them (the rows it still held are counted in
`record.rows_not_written`, not written). summary.json `record.state` is then `incomplete`.

Nothing in the pipe is lost when the loop's process ends unexpectedly: the writer reads what
the pipe holds to the end, closes log.csv, timing.csv and events.jsonl, and finishes run.mcap
(its index written); only rows still waiting in the loop's process (none unless the writer had
fallen a pipe's worth behind) go with it. The writer ignores Ctrl-C and SIGTERM (the loop
handles them and closes the log in order: nothing it does waits for the writer unbounded). Row
ordering and content are the loop's; a lock-step log is the same bytes whoever writes it.

The live view (`hil run --live`) serves the messages from the loop's process: a run with
further message sinks keeps its RunLog there (`open_run_log`).
"""

from __future__ import annotations

import contextlib
import ctypes
import itertools
import os
import pickle
import select
import signal
import struct
import sys
import time
from collections import deque
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from hil.output import channels as ch
from hil.output.channels import MessageSink
from hil.output.record_files import RecordWriteError
from hil.output.runlog import (
    PAPER_TERM_COLUMNS,
    RECORD_INCOMPLETE,
    RecordState,
    RunLog,
    per_joint_columns,
    write_summary_file,
)
from hil.output.writer_watch import StallWatch, WriterProgress, WriterStatus

if TYPE_CHECKING:
    from drivers.peer_wait import PeerActivity

_HEADER = struct.Struct("<II")  # record type, payload bytes
_STRING_ID = struct.Struct("<I")
_ROW, _STRING, _EVENT, _CLOSE, _SUMMARY, _FINISH = range(1, 7)
_TIMING_VALUES = 6  # tick, read_s, compute_s, write_s, log_s, time_s
_PIPE_BYTES = 1 << 20  # the pipe's size where the OS allows it (~600 humanoid ticks)
# What the loop keeps for a writer that is behind (the pipe full): ~9000 humanoid ticks, ~45 s
# of the run and a few seconds of the writer's work; a writer further behind is lost.
BACKLOG_BYTES = 16 << 20
POLL_S = 0.005  # the writer reads the pipe this often (it is never woken by the loop)
REAP_S = 1.0  # a writer told to end, or killed, is waited for this long (then left)
_LOOK_S = 0.02  # a wait for the writer's answer looks at its progress this often
_F_SETPIPE_SZ = 1031  # fcntl on Linux
_PR_SET_NAME = 15  # linux/prctl.h
WRITER_PROCESS_NAME = b"hil-log-writer"

# events.jsonl kinds of a lost writer (see the module docstring)
WRITER_STALLED = "log_writer_stalled"
WRITER_LOST = "log_writer_lost"
RECORD_WRITE_FAILED = "record_write_failed"


def never_preempt_the_loop() -> None:
    """This (helper) process at SCHED_BATCH where the OS has it: a batch task that wakes up
    does not take the CPU from the task running there (the loop); it runs on an idle CPU or
    when the loop waits. Any user may lower a process to it."""
    with contextlib.suppress(AttributeError, OSError):
        os.sched_setscheduler(0, os.SCHED_BATCH, os.sched_param(0))


class LogWriterLost(OSError):
    """The log writer process ended (or its record could not be written) before the run did:
    the run stops as on a lost bus; the loop writes the record's rest itself."""


class LogWriterStalled(LogWriterLost):
    """The log writer process stalled (hil/output/writer_watch.py): handled as a lost one."""


def open_run_log(
    out_dir: Path,
    joint_names: Sequence[str],
    meta: dict[str, Any],
    sensor_columns: Sequence[str],
    *,
    mcap: bool,
    sinks: Sequence[MessageSink] = (),
    term_columns: Sequence[str] = PAPER_TERM_COLUMNS,
    activity: Callable[[int], PeerActivity | None] | None = None,
) -> RunLog | LogProcess:
    """The run's log: written by a process of its own, or in this one when there are further
    message sinks (the live view's server lives here) or no fork. term_columns: the
    controller's logged terms (`hil.output.runlog.per_joint_columns`); activity: how to look
    at the writer's process (hil.wiring.process_activity.ProcessActivity) so that a slow one
    that works is told from a stalled one (hil/output/writer_watch.py)."""
    if sinks or not hasattr(os, "fork"):
        return RunLog(
            out_dir, joint_names, meta, sensor_columns, mcap=mcap, sinks=sinks,
            term_columns=term_columns,
        )  # fmt: skip
    return LogProcess(
        out_dir,
        joint_names,
        meta,
        sensor_columns,
        mcap=mcap,
        term_columns=term_columns,
        activity=activity,
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


class _Loss:
    """How the writer was lost, for the record."""

    def __init__(self, kind: str, why: str, tick: int, time_s: float) -> None:
        self.kind = kind
        self.why = why
        self.tick = tick
        self.time_s = time_s

    @property
    def write_failed(self) -> bool:
        return self.kind == RECORD_WRITE_FAILED

    def record(self) -> dict[str, Any]:
        return {"kind": self.kind, "problem": self.why, "tick": self.tick, "time_s": self.time_s}


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
        activity: Callable[[int], PeerActivity | None] | None = None,
    ) -> None:
        self.dir = Path(out_dir)
        self.rows = 0
        self.closed = False
        self._names = (tuple(joint_names), tuple(sensor_columns), tuple(term_columns))
        self._mcap = mcap
        columns = per_joint_columns(term_columns)
        self._layout = _RowLayout(len(joint_names), len(sensor_columns), columns)
        record = bytearray(_HEADER.size + 8 * self._layout.size)
        _HEADER.pack_into(record, 0, _ROW, 8 * self._layout.size)
        self._record = record
        self._row = np.frombuffer(memoryview(record)[_HEADER.size :], dtype=np.float64)
        self._strings: dict[str, int] = {}
        self._loss: _Loss | None = None  # why the writer is gone
        self._loss_raised = False  # write_tick has raised it: the loop knows
        self._finished = False
        self._mcap_finished = not mcap  # the writer finished run.mcap (with the summary)
        self._last_tick, self._last_time_s = -1, 0.0
        # every record handed over that the writer has not said it handled, from number
        # self._first_kept on (records are numbered from 1), and what the pipe has not taken
        self._kept: deque[bytes] = deque()
        self._first_kept = 1
        self._kept_bytes = 0
        self._sent = 0
        self._unsent: deque[memoryview] = deque()
        self._local: RunLog | None = None  # the record as the loop writes it, once lost
        self._rows_not_written = 0
        self._unreaped: int | None = None  # a killed writer that did not go (stuck in the kernel)
        self._progress = WriterProgress()
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
            _serve(rows_read, acks_written, self._progress, args, self._layout)  # never returns
        os.close(rows_read)
        os.close(acks_written)
        os.set_blocking(self._to_writer, False)
        self._watch = StallWatch(self.pid, activity(self.pid) if activity is not None else None)
        self._await("opening the run log")
        if self._loss is not None:  # nothing to take over: the run cannot start
            self._progress.close()
            raise LogWriterLost(self._loss.why)

    # --- per tick ------------------------------------------------------------------------
    def write_tick(self, row: tuple, timing: tuple) -> None:
        """One tick's log.csv row (`RunLog.write_row`'s arguments) and timing.csv row
        (`RunLog.write_timing`'s), in one record of ~8 bytes a number. Never waits for the
        writer; raises LogWriterLost (once) when it has been lost: the row is kept all the
        same, and written by the loop at the end."""
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
        self._last_tick, self._last_time_s = int(tick), max(self._last_time_s, float(time_s))
        self._send(bytes(self._record))
        self.rows += 1
        if self._loss is not None and not self._loss_raised:
            self._loss_raised = True
            kind = LogWriterStalled if self._loss.kind == WRITER_STALLED else LogWriterLost
            raise kind(f"{self._loss.why}: the run stops")

    def event(self, time_s: float, kind: str, message: str, **fields: Any) -> None:
        """One line of events.jsonl. Never raises: a writer that was lost is said by the next
        `write_tick` (events are also said on every exit path, which must go on)."""
        if not self.closed:
            self._last_time_s = max(self._last_time_s, time_s)
            self._send_record(_EVENT, pickle.dumps((time_s, kind, message, fields)))

    # --- the end -------------------------------------------------------------------------
    def close(self) -> None:
        """log.csv, timing.csv and events.jsonl complete on disk (run.mcap stays open for the
        summary); by the loop from where the writer stopped, if it was lost."""
        if self.closed:
            return
        self.closed = True
        if self._loss is None:
            self._send_record(_CLOSE, b"")
            self._await("closing the log files")
        if self._loss is not None:
            self._take_over().close()

    def write_summary(self, summary: dict[str, Any]) -> None:
        """summary.json, with `record` (`record_report`), and run.mcap finished (the writer
        ends). Raises RecordWriteError if summary.json could not be written."""
        if self._loss is None:
            self._send_record(_SUMMARY, pickle.dumps(summary))
            self._await("writing the summary")
            if self._loss is None:
                self._finished = self._mcap_finished = True
        try:
            if self._loss is not None:  # summary.json written from here
                self._take_over()
                write_summary_file(self.dir, {**summary, "record": self.record_report()})
        finally:
            self.finish_sinks()

    def finish_sinks(self) -> None:
        """The writer's end: everything written, run.mcap finished."""
        if self._loss is None and not self._finished:
            self._send_record(_FINISH, b"")
            self._await("finishing the log")
        if self._loss is not None:
            self._take_over().finish_sinks()
        self._finished = self.closed = True  # nothing more to write: close() does nothing
        self._end_writer()
        self._progress.close()

    def __enter__(self) -> LogProcess:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()
        self.finish_sinks()

    # --- what the record says of itself ---------------------------------------------------
    def record_report(self) -> dict[str, Any]:
        """summary.json's `record` (as the loop knows it: a writer that is not lost adds its
        own, RunLog.record_report)."""
        loss, local = self._loss, self._local
        if loss is None:
            return {"state": str(RecordState.COMPLETE), "rows": self.rows}
        by_loop = local.rows if local is not None else 0
        not_written = self._rows_not_written + (local.rows_not_written if local else 0)
        events_lost = local.events_not_written if local is not None else 0
        whole = not_written == 0 and events_lost == 0
        report: dict[str, Any] = {
            "state": str(RecordState.WRITTEN_BY_LOOP if whole else RecordState.INCOMPLETE),
            "rows": self.rows,
            "writer": loss.record(),
            "rows_by_writer": self.rows - by_loop - not_written,
            "rows_by_loop": by_loop,
            "rows_not_written": not_written,
            "events_not_written": events_lost,
        }
        if local is not None and local.write_error is not None:
            report["problem"] = str(local.write_error)
        if not self._mcap_finished:
            report["run_mcap"] = (
                "unfinished: the writer ended before writing its index (mcap recover rebuilds it)"
            )
        if self._unreaped is not None:
            report["writer_process"] = (
                f"process {self._unreaped} did not end when killed (stuck in the kernel)"
            )
        return report

    def record_note(self) -> str | None:
        """One line for the exit notes when the record is not the writer's whole work."""
        loss = self._loss
        if loss is None:
            return None
        report = self.record_report()
        if report["state"] == RecordState.INCOMPLETE:
            problem = report.get("problem", loss.why)
            whole = report["rows_by_writer"] + report["rows_by_loop"]
            return (
                f"{RECORD_INCOMPLETE}: {problem}; {whole} rows whole on disk, "
                f"{report['rows_not_written']} not written"
            )
        return f"record: {loss.why}, at tick {loss.tick}; the loop wrote the rest"

    # --- the pipe ------------------------------------------------------------------------
    def _string_id(self, text: str) -> int:
        number = self._strings.get(text)
        if number is None:
            number = self._strings[text] = len(self._strings)
            self._send_record(_STRING, _STRING_ID.pack(number) + text.encode())
        return number

    def _send_record(self, kind: int, payload: bytes) -> None:
        self._send(_HEADER.pack(kind, len(payload)) + payload)

    def _send(self, record: bytes) -> None:
        """Hand a record over without waiting; kept until the writer has handled it."""
        self._sent += 1
        self._kept.append(record)
        self._kept_bytes += len(record)
        if self._loss is not None or self._to_writer < 0:  # (kept for the loop to write)
            return
        if self._unsent:
            self._unsent.append(memoryview(record))
            self._drain()
        else:
            try:
                written = os.write(self._to_writer, record)
            except BlockingIOError:
                written = 0
            except OSError as exc:  # the writer has ended: its end of the pipe is closed
                self._lose(WRITER_LOST, self._ended(exc))
                return
            if written < len(record):
                self._unsent.append(memoryview(record)[written:])
        self._check_progress()

    def _drain(self) -> None:
        """What the pipe did not take, as far as it takes it now."""
        unsent = self._unsent
        while unsent and self._loss is None:
            buffers = list(itertools.islice(unsent, 64))
            try:
                written = os.writev(self._to_writer, buffers)
            except BlockingIOError:
                return
            except OSError as exc:
                self._lose(WRITER_LOST, self._ended(exc))
                return
            full = written < sum(len(b) for b in buffers)
            while written:
                first = unsent[0]
                if len(first) <= written:
                    written -= len(first)
                    unsent.popleft()
                else:
                    unsent[0] = first[written:]
                    written = 0
            if full:
                return

    def _ended(self, exc: OSError) -> str:
        why = (exc.strerror or str(exc)).lower()
        return f"the log writer process ({self.pid}) ended ({why}: its end of the pipe is closed)"

    def _check_progress(self, owed_answer: int = 0) -> None:
        """Forget what the writer has handled; find it stalled or too far behind."""
        if self._unsent:  # (what the pipe did not take, before the writer is judged)
            self._drain()
            if self._loss is not None:
                return
        done = self._progress.records_done()
        kept = self._kept
        while kept and self._first_kept <= done:
            self._kept_bytes -= len(kept.popleft())
            self._first_kept += 1
        behind = self._sent - done
        if self._watch.check(done, behind + owed_answer, self._progress.looks()):
            self._lose(WRITER_STALLED, self._watch.describe(behind))
        elif self._kept_bytes > BACKLOG_BYTES:
            self._lose(
                WRITER_STALLED,
                f"the log writer (process {self.pid}) fell more than "
                f"{BACKLOG_BYTES >> 20} MB behind the loop",
            )

    def _await(self, what: str) -> None:
        """The writer's answer to the last request ("ok", or why it failed), waited for while
        it makes progress (`_check_progress`); a writer lost meanwhile sets `_loss`."""
        while self._loss is None:
            self._drain()
            if self._loss is not None:
                return
            writable = (self._to_writer,) if self._unsent else ()
            readable = select.select((self._acks,), writable, (), _LOOK_S)[0]
            if readable:
                answer = self._read_answer()
                if not answer.startswith("ok"):
                    why = f"the log writer process ({self.pid}) ended ({what})"
                    self._lose(WRITER_LOST, why, answer)
                return
            self._check_progress(owed_answer=1)

    def _read_answer(self) -> str:
        try:
            return os.read(self._acks, 4096).decode(errors="replace")
        except OSError:
            return ""

    def _lose(self, kind: str, why: str, answer: str | None = None) -> None:
        """The writer is lost (see the module docstring): ended, the loss in the record.
        `answer`: what it said before it went (read now if not given)."""
        if self._loss is not None:
            return
        if kind == WRITER_LOST:
            if answer is None and self._acks >= 0 and select.select((self._acks,), (), (), 0)[0]:
                answer = self._read_answer()
            said = (answer or "").strip()
            if said and self._progress.status is WriterStatus.WRITE_FAILED:
                failure = said.removeprefix(f"{RecordWriteError.__name__}: ")
                kind, why = RECORD_WRITE_FAILED, f"the run's record cannot be written: {failure}"
            elif said and not said.startswith("ok"):
                why = f"{why}: {said}"
        owed = self._sent - self._progress.records_done()
        self._loss = _Loss(kind, why, self._last_tick, self._last_time_s)
        self._end_writer()
        # among the other events, in order (written when the loop takes the record over)
        fields = {"tick": self._last_tick, "records_owed": owed}
        message = f"{why}; the loop writes the record from here on"
        self._send_record(_EVENT, pickle.dumps((self._last_time_s, kind, message, fields)))

    def _end_writer(self) -> None:
        """The writer gone: told to end by its pipe's end, else killed; waited for at most
        REAP_S each time, never blocking."""
        for fd in (self._to_writer, self._acks):
            with contextlib.suppress(OSError):
                if fd >= 0:
                    os.close(fd)
        self._to_writer = self._acks = -1
        if not self.pid:
            return
        if self._loss is not None or not self._reaped(REAP_S):
            with contextlib.suppress(ProcessLookupError):
                os.kill(self.pid, signal.SIGKILL)  # a stopped process ends too
            if not self._reaped(REAP_S):
                self._unreaped = self.pid
        self.pid = 0

    def _reaped(self, within_s: float) -> bool:
        deadline = time.monotonic() + within_s
        while True:
            try:
                pid, _ = os.waitpid(self.pid, os.WNOHANG)
            except ChildProcessError:  # reaped already
                return True
            if pid:
                return True
            if time.monotonic() > deadline:
                return False
            time.sleep(0.002)

    # --- the record written by the loop ---------------------------------------------------
    def _take_over(self) -> RunLog:
        """The record from where the writer stopped, written from here (see the module
        docstring); once."""
        if self._local is not None:
            return self._local
        loss = self._loss
        assert loss is not None, "only a lost writer's record is taken over"
        done, sizes = self._progress.read()
        joint_names, sensor_columns, term_columns = self._names
        local = RunLog(
            self.dir, joint_names, {}, sensor_columns, term_columns=term_columns, resume=sizes
        )
        self._local = local
        replay = _Writer(local, self._layout, None)
        replay.strings = {number: text for text, number in self._strings.items()}
        for number, record in enumerate(self._kept, start=self._first_kept):
            kind, _ = _HEADER.unpack_from(record)
            if number <= done or kind in (_CLOSE, _SUMMARY, _FINISH):
                continue
            if kind == _ROW and loss.write_failed:  # no room: the end's events go in
                self._rows_not_written += 1
                continue
            with contextlib.suppress(RecordWriteError):  # counted by the local log
                replay.handle(kind, record[_HEADER.size :])
        self._kept.clear()
        return local


def _serve(rows: int, acks: int, progress: WriterProgress, args: tuple, layout: _RowLayout) -> None:
    """The writer: a RunLog fed from the pipe until FINISH or the loop's end of it closes."""
    code = 0
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        never_preempt_the_loop()
        _name_this_process()
        out_dir, joint_names, meta, sensor_columns, mcap, terms = args
        log = RunLog(
            Path(out_dir), joint_names, meta, sensor_columns, mcap=mcap, term_columns=terms
        )
        progress.publish(0, log.sizes())
        os.write(acks, b"ok\n")
        _Writer(log, layout, acks, progress).run(rows)
    except BaseException as exc:  # noqa: BLE001 - said to the loop, then the writer ends
        if isinstance(exc, RecordWriteError):
            progress.status = WriterStatus.WRITE_FAILED
        with contextlib.suppress(OSError):
            os.write(acks, f"{type(exc).__name__}: {exc}\n".encode())
        code = 1
    finally:
        os._exit(code)  # no atexit, no flush of the loop's buffers copied at the fork


def _name_this_process() -> None:
    with contextlib.suppress(OSError, AttributeError):
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_NAME, ctypes.c_char_p(WRITER_PROCESS_NAME), 0, 0, 0)


class _Writer:
    """The writer's side of the pipe: records in, the RunLog's calls out (also the loop's, for
    the records a lost writer had not handled: no answers, no progress)."""

    def __init__(
        self,
        log: RunLog,
        layout: _RowLayout,
        acks: int | None,
        progress: WriterProgress | None = None,
    ) -> None:
        self.log = log
        self.layout = layout
        self.acks = acks
        self.progress = progress
        self.strings: dict[int, str] = {}
        n, start = layout.n, layout.joints
        self.columns = []
        for c, name in enumerate(layout.columns):
            kind = bool if name in ch.BOOL_COLUMNS else int if name in ch.INTEGER_COLUMNS else None
            self.columns.append((slice(start + c * n, start + (c + 1) * n), kind))

    def run(self, rows: int) -> None:
        """Read what the pipe holds every POLL_S: a writer blocked in read() would be woken by
        every row the loop writes, and the kernel runs a task woken through a pipe on the
        waker's CPU when it can (the loop's), taking it from the loop each tick. Each record
        handled is said to the loop (`WriterProgress`); a write that failed ends the writer."""
        assert self.progress is not None
        os.set_blocking(rows, False)
        pending = bytearray()
        handled = 0
        while True:
            try:
                chunk = os.read(rows, _PIPE_BYTES)
            except BlockingIOError:
                self.progress.looked()
                time.sleep(POLL_S)
                continue
            self.progress.looked()
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
                going_on = self.handle(kind, payload)
                if self.log.write_error is not None:  # an event's, which does not raise
                    raise self.log.write_error
                handled += 1
                self.progress.publish(handled, self.log.sizes())
                if not going_on:
                    return
            del pending[:offset]

    def handle(self, kind: int, payload: bytes) -> bool:
        """One record; False after the last."""
        log = self.log
        if kind == _ROW:
            self.row(np.frombuffer(payload, dtype=np.float64))
        elif kind == _STRING:
            (number,) = _STRING_ID.unpack_from(payload)
            self.strings[number] = payload[_STRING_ID.size :].decode()
        elif kind == _EVENT:
            time_s, event_kind, message, fields = pickle.loads(payload)
            log.event(time_s, event_kind, message, **fields)
        elif kind == _CLOSE:
            log.close()
            self.answer()
        elif kind == _SUMMARY:
            log.write_summary(pickle.loads(payload))
            self.answer()
        elif kind == _FINISH:
            log.close()
            log.finish_sinks()
            self.answer()
            return False
        return True

    def answer(self) -> None:
        if self.acks is not None:
            os.write(self.acks, b"ok\n")

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
