"""A comparison's runs N at a time, each in a worker process (`run_in_workers`).

A worker is a `spawn`ed interpreter (not a fork: the parent may hold threads - tqdm's monitor,
a live view - which a fork would copy in whatever state they were) holding a copy of the
parent's `Session`. It runs each run it is given exactly as the serial plan does
(`Session.run_one`: its own embedded emulator, the same configuration, seed and directory, so
the same log), draws the run's figures, and sends the result back. The parent gives an idle
worker the next run, longest experiment first (the short runs fill the gaps at the end),
collects the results in plan order, and moves one bar over the whole plan.

Stopping. A terminal's Ctrl-C reaches every worker (they share the terminal's process group; an
emulator does not, its worker stops it); a SIGINT or SIGTERM sent to the parent alone is passed
on to the workers that have a run. Either way the worker's `StopFlag` ends its run through the
loop's own exit path (torque off, the log complete, summary.json), the worker starts no other
run, and the parent gives out no more, takes the running runs' results and ends the workers.
A worker given a run it has not begun skips it: the parent sets the plan's stop (an Event)
before it signals. The workers start with both signals ignored (until their own handlers are
in place a signal would kill them half-started); the parent ignores them for the few
milliseconds of starting the processes. No worker outlives the plan: each is told to leave and
joined; one that does not leave is terminated, then killed.

Messages, worker -> parent (one pipe per worker): ("started",), ("say", text),
("progress", fraction of the run), ("done", RunResult: a run that raised is a failed run,
hil.session.plan), ("stops", exception: one of STOPS_THE_PLAN), ("skipped",) (stopped before
it began).
"""

from __future__ import annotations

import contextlib
import dataclasses
import multiprocessing
import os
import pickle
import signal
import time
from collections import deque
from collections.abc import Sequence
from multiprocessing.connection import Connection, wait
from typing import Any

from hil.loop import StopFlag
from hil.output.progress import Progress
from hil.output.records import RunEntry, RunResult
from hil.session.plan import STOPS_THE_PLAN, PlannedRun, failed_run, run_planned
from hil.session.session import Session, SessionError
from sim_backend.scenario import FaultEvent

POLL_S = 0.25  # how soon the parent sees a signal while it waits for its workers
LEAVE_S = 10.0  # for an idle worker to leave when told, before it is terminated
# for a stopped run to come back (the loop's exit path: stop cycles, torque off, the log)
STOPPED_RUN_S = 60.0
SIGNALS = (signal.SIGINT, signal.SIGTERM)


class _Relay(Progress):
    """The worker's side of the parent's bar: the session's lines and its run's progress go
    through the pipe."""

    def __init__(self, conn: Connection) -> None:
        super().__init__(1, unit="run", desc="run", enabled=False)
        self.conn = conn

    def update_to(self, done: float, text: str | None = None) -> None:
        self.conn.send(("progress", float(done)))

    def write(self, text: str, file: Any = None) -> None:
        self.conn.send(("say", text))


def _worker_main(
    conn: Connection,
    plan_stopped: Any,  # a multiprocessing Event: the parent stopped the plan
    session: Session,
    faults: tuple[FaultEvent, ...],
    overruns: tuple[tuple[float, float], ...],
) -> None:
    """A worker: runs until told to leave (None) or its parent is gone (then a running run
    meets the broken pipe at its next line or progress: an error, through its exit path)."""
    stop = StopFlag()
    stop.install()  # SIGINT, SIGTERM: end the run through its exit path, start no other
    session.progress = _Relay(conn)
    session.progress_done = 0.0
    try:
        while (run := conn.recv()) is not None:
            if stop.reason is not None or plan_stopped.is_set():
                conn.send(("skipped",))
                continue
            conn.send(("started",))
            conn.send(_run(session, run, faults, overruns, stop))
    except (EOFError, OSError):  # the parent is gone
        return


def _run(
    session: Session,
    run: PlannedRun,
    faults: tuple[FaultEvent, ...],
    overruns: tuple[tuple[float, float], ...],
    stop: StopFlag,
) -> tuple[Any, ...]:
    try:
        return ("done", run_planned(session, run, faults, overruns, stop))
    except STOPS_THE_PLAN as exc:
        try:
            pickle.dumps(exc)
        except Exception:  # noqa: BLE001 - an exception that cannot travel: its words do
            return ("stops", SessionError(str(exc)))
        return ("stops", exc)


@dataclasses.dataclass
class _Worker:
    process: multiprocessing.process.BaseProcess
    conn: Connection
    run: PlannedRun | None = None  # the run it has
    started: bool = False  # it said it began that run
    fraction: float = 0.0  # of that run, done
    signalled: bool = False  # the parent's stop was passed on to it
    gone: bool = False  # its process ended, or its pipe broke

    def give(self, run: PlannedRun) -> bool:
        try:
            self.conn.send(run)
        except OSError:  # BrokenPipeError: it is gone
            self.gone = True
            return False
        self.run, self.started, self.fraction, self.signalled = run, False, 0.0, False
        return True


class PlanProgress:
    """The parent's view of a plan run by several workers: a line when a run starts and when
    it ends (they end out of order), and one bar over the whole plan (runs done plus the
    running runs' fractions, so its ETA counts every worker)."""

    def __init__(self, session: Session, bar: Progress, total: int) -> None:
        self.session, self.bar, self.total = session, bar, total
        self.started = self.finished = 0

    def run_started(self, run: PlannedRun, workers: Sequence[_Worker]) -> None:
        self.started += 1
        self.session.say(f"[{self.started}/{self.total}] {run.what}")
        self.moved(workers)

    def run_ended(self, run: PlannedRun, result: RunResult, workers: Sequence[_Worker]) -> None:
        self.finished += 1
        self.session.say(f"[{self.finished}/{self.total} done] {run.what}: {result.ending}")
        self.moved(workers)

    def moved(self, workers: Sequence[_Worker]) -> None:
        running = [(w.run, w.fraction) for w in workers if w.run is not None and w.started]
        done = self.finished + sum(fraction for _, fraction in running)
        self.bar.update_to(done, " | ".join(run.what for run, _ in running) or None)


class _Pool:
    """The worker processes of one plan, and what came back from them."""

    def __init__(
        self,
        count: int,
        session: Session,
        faults: tuple[FaultEvent, ...],
        overruns: tuple[tuple[float, float], ...],
        view: PlanProgress,
    ) -> None:
        context = multiprocessing.get_context("spawn")
        self.plan_stopped = context.Event()
        self.view = view
        self.results: dict[int, RunResult] = {}
        self.stops: list[BaseException] = []  # what stopped the plan (STOPS_THE_PLAN)
        self.workers: list[_Worker] = []
        # the parent's bar and live view stay here; each worker relays to the bar
        template = dataclasses.replace(session, progress=None, sinks=(), emulator_fault_counts={})
        previous = {sig: signal.signal(sig, signal.SIG_IGN) for sig in SIGNALS}  # inherited
        try:
            for number in range(count):
                mine, theirs = context.Pipe()
                process = context.Process(
                    target=_worker_main,
                    args=(theirs, self.plan_stopped, template, faults, overruns),
                    name=f"hil-run-worker-{number + 1}",
                    # not daemonic: a run may start processes of its own (the LQR's designer,
                    # the log writer), which a daemonic process may not; `end` (always run)
                    # joins every worker, and one whose parent is gone leaves at its next
                    # message (EOF)
                    daemon=False,
                )
                process.start()
                theirs.close()
                self.workers.append(_Worker(process, mine))
        except BaseException:
            self.end()  # the workers started so far
            raise
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, handler)

    @property
    def busy(self) -> list[_Worker]:
        return [w for w in self.workers if w.run is not None]

    def give(self, pending: deque[PlannedRun]) -> None:
        """The next runs to the idle workers."""
        for worker in self.workers:
            if worker.run is None and not worker.gone and pending:
                run = pending.popleft()
                if not worker.give(run):
                    pending.appendleft(run)

    def receive(self, timeout_s: float) -> None:
        """What the busy workers sent within `timeout_s`."""
        busy = self.busy
        wait([w.conn for w in busy] + [w.process.sentinel for w in busy], timeout=timeout_s)
        for worker in busy:
            self._receive(worker)

    def _receive(self, worker: _Worker) -> None:
        """What `worker` sent so far; a worker gone with a run is that run's failure."""
        run, view = worker.run, self.view
        try:
            while run is not None and worker.conn.poll():
                kind, *rest = worker.conn.recv()
                if kind == "started":
                    worker.started = True
                    view.run_started(run, self.workers)
                elif kind == "say":
                    view.session.say(rest[0])
                elif kind == "progress":
                    worker.fraction = min(max(rest[0], 0.0), 1.0)
                    view.moved(self.workers)
                else:  # the run is over: done, stops or skipped
                    worker.run = None
                    if kind == "stops":
                        self.stops.append(rest[0])
                    elif kind == "done":
                        self._ended(run, rest[0])
                    return
        except (EOFError, OSError):
            pass
        if run is not None and not worker.process.is_alive():
            worker.run, worker.gone = None, True
            code = worker.process.exitcode
            how = f"signal {signal.Signals(-code).name}" if code and code < 0 else f"status {code}"
            self._ended(run, failed_run(run, f"its worker process ended ({how})"))

    def _ended(self, run: PlannedRun, result: RunResult) -> None:
        self.results[run.number] = result
        self.view.run_ended(run, result, self.workers)

    def stop(self, reason: str | None) -> None:
        """The plan stopped: no worker begins another run, and each with a run (once) ends it
        as a signal to a serial `hil run` would (the parent's own signal, else SIGTERM)."""
        self.plan_stopped.set()  # before the signals: a worker that misses one sees this
        signum = signal.Signals.__members__.get(reason or "", signal.SIGTERM)
        for worker in self.busy:
            if not worker.signalled and worker.process.pid is not None:
                with contextlib.suppress(ProcessLookupError):
                    os.kill(worker.process.pid, signum)
                worker.signalled = True

    def end(self) -> None:
        """Every worker gone: running runs stopped and their results taken first (after an
        unexpected exit from the plan), then each worker told to leave and joined; one that
        stays is terminated, then killed."""
        if self.busy:
            self.stop("SIGTERM")
            deadline = time.monotonic() + STOPPED_RUN_S
            while self.busy and time.monotonic() < deadline:
                self.receive(POLL_S)
        for worker in self.workers:
            with contextlib.suppress(OSError):
                worker.conn.send(None)
        for worker in self.workers:
            process = worker.process
            process.join(LEAVE_S)
            if process.is_alive():
                process.terminate()
                process.join(LEAVE_S)
            if process.is_alive():
                process.kill()
                process.join()
            worker.conn.close()


def run_in_workers(
    session: Session,
    runs: Sequence[PlannedRun],
    workers: int,
    *,
    faults: tuple[FaultEvent, ...],
    overruns: tuple[tuple[float, float], ...],
    stop: StopFlag,
    bar: Progress,
) -> list[RunEntry]:
    """Every run of `runs` on `workers` worker processes; the entries of the runs that began,
    in plan order. Raises what stopped the plan (`STOPS_THE_PLAN`) once the other runs are
    over."""
    pool = _Pool(workers, session, faults, overruns, PlanProgress(session, bar, len(runs)))
    pending = deque(sorted(runs, key=lambda run: -run.experiment.duration_s))
    try:
        while True:
            if stop.reason is not None or pool.stops:
                pending.clear()
                pool.stop(stop.reason)
            pool.give(pending)
            if not pool.busy:
                if not pending or all(w.gone for w in pool.workers):
                    break
                continue
            pool.receive(POLL_S)
    finally:
        pool.end()
    if pool.stops:
        raise pool.stops[0]
    return [
        RunEntry(run.experiment.name, run.choice, pool.results[run.number])
        for run in runs
        if run.number in pool.results
    ]
