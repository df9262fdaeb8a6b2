"""Rescheduling the LQR gain with posture and contact, off the 200 Hz path.

On the humanoid, Sm of (19) changes with the leg posture and with the LQR's contact (one sole or
both), and the LQR gain designed on it must follow (the lab's code recomputes it in a background
thread every 100 ms). A design runs in a worker process, never inside a tick's compute:

    lock-step   a design is requested at tick k from the posture measured at k and installed
                at tick k + `lead_ticks` exactly (the tick waits for it only if it is not done
                by then): while the worker designs, the loop waits for the emulated robot, which
                steps in its own process. The gain in force at every tick depends on the run's
                samples only, never on timing: a lock-step run stays deterministic.
                The contact schedule is known ahead (the experiment's phases), so the design for
                a new contact is requested `lead_ticks` before it and installed on the tick it
                starts.
    wall clock  the same requests; a finished design is installed at the start of the first
                tick after it is done (a tick never waits for it). The design runs only while
                the loop sleeps between ticks (`tick_active`).

Designs are requested every `period_ticks` and at every contact change (the doubling solver of
controller/lqr_designs.py: 1-6 ms for the lab's diagonal design, 5-30 ms for the closed chain on
the servo cascade on this machine), with one BLAS thread: on this 2-core machine a threaded BLAS
made a 36-state DARE take 138 ms instead of 52 ms (docs/walking.md), and a single-threaded
reduction is the same bits every run.

Why a process and not a thread: a design is thousands of small numpy and pinocchio calls that
hold the interpreter's lock between them. In a thread it made the loop wait for the lock each
time the loop's thread came back from the kernel (a reply arrived, a sleep ended): measured on
this machine, a 5 ms loop woke 1.6-2.9 ms late (median) while a design ran beside it, 0.13 ms
otherwise; with the design in a process, 0.19-0.25 ms. The worker is forked from the loop's
process when the scheduler is built (it has the robot model and the designer as they are then,
and keeps the designer's warm start between designs); requests and gains travel through a pipe
(`_DesignProcess`). Where fork is not available, the designs run in a thread as before.
Each design's latency (request to use) and compute time are recorded for the summary.

Waiting for a design (lock-step) is bounded by the designer's progress, not by a time: it is
waited for while it runs or waits for a CPU (a loaded machine), however long; one that has
made no progress for DESIGNER_STALL_S (stopped, or asleep while a design is due:
hil/wiring/process_activity.py) has stalled, and one whose process ended is gone. Either is
`GainDesignerLost`, which stops the run as a lost bus does (torque off on its exit path), its
message saying what stalled, since when and at which tick. A stop (Ctrl-C, SIGTERM: the loop's
StopFlag) ends the wait at once: the gain in force stays, and the loop ends at its next tick.
The designer dies with the loop's process (PR_SET_PDEATHSIG: SIGKILL, which acts on a stopped
process too) and holds none of its descriptors (a port, a pipe, the fork server's socket that
keeps the emulators alive until its last holder is gone).
"""

from __future__ import annotations

import contextlib
import ctypes
import multiprocessing
import os
import pickle
import signal
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from controller import JointController
from controller.lqr import TrackingGain
from drivers.peer_wait import PeerWait
from hil.controllers.robot_model import RobotModel
from hil.loop.request import StopFlag
from hil.output.log_process import never_preempt_the_loop
from hil.wiring.process_activity import ProcessActivity, proc_available

LOCKSTEP_LEAD_TICKS = 4  # a design requested at tick k is in force from tick k + 4 (20 ms)
# A designer that neither ran nor waited for a CPU for this long while a design was due has
# stalled (a design takes 1-30 ms of CPU here; a runnable one is waited for however long).
DESIGNER_STALL_S = 1.0
_LOOK_S = 0.02  # how often a wait for a design looks at the designer and the stop flag
_PR_SET_PDEATHSIG = 1  # linux/prctl.h
_PR_SET_NAME = 15
DESIGNER_PROCESS_NAME = b"hil-designer"  # its name in ps -o comm, top


class GainDesignerLost(OSError):
    """The gain designer's process ended or stalled while the loop waited for a design: the
    run stops as on a lost bus (an OSError, like hil.output.log_process.LogWriterLost)."""


@dataclass
class _Request:
    link_angle_rad: np.ndarray
    contact: object
    requested_s: float
    due_tick: int


@dataclass
class GainSchedule:
    """What the scheduler did: designs used, their latency (request to use), compute time and
    how long a tick waited for one [s]."""

    designs: int = 0
    latencies_s: list[float] = field(default_factory=list)
    compute_s: list[float] = field(default_factory=list)
    waited_s: list[float] = field(default_factory=list)

    def record(self) -> dict[str, object]:
        def stats(values: list[float]) -> tuple[float | None, float | None]:
            array = np.asarray(values)
            return (float(np.median(array)), float(array.max())) if array.size else (None, None)

        latency, compute, waited = (
            stats(self.latencies_s),
            stats(self.compute_s),
            stats(self.waited_s),
        )
        return {
            "designs": self.designs,
            "latency_median_s": latency[0],
            "latency_max_s": latency[1],
            "compute_median_s": compute[0],
            "compute_max_s": compute[1],
            "tick_wait_max_s": waited[1],
        }


Design = tuple["TrackingGain | Exception", float]  # the gain (or why not) and its compute time


class _DesignProcess:
    """The designs in a forked child process; requests and gains through a pipe."""

    def __init__(self, robot: RobotModel, designer: Any) -> None:
        context = multiprocessing.get_context("fork")
        self._connection, child = context.Pipe()
        inherited = _open_descriptors() - {child.fileno()}  # the child closes these
        self._process = context.Process(
            target=_serve,
            args=(child, robot, designer, os.getpid(), inherited),
            name="gain-designer",
            daemon=True,
        )
        self._process.start()
        child.close()
        self._ended = False
        self._paused = False
        self._lost: str | None = None  # why the designer was given up (stalled or ended)
        self._watch = (
            PeerWait(
                ProcessActivity(self._process.pid),
                idle_window_s=DESIGNER_STALL_S,
                look_interval_s=_LOOK_S,
            )
            if self._process.pid is not None and proc_available()
            else None
        )

    def submit(self, link_angle_rad: np.ndarray, contact: object) -> None:
        try:
            self._connection.send((link_angle_rad, contact))
        except OSError:  # it has ended: `result` says so
            self._ended = True

    def done(self) -> bool:
        return self._ended or self._connection.poll()

    def result(self, stopped: Callable[[], bool] = lambda: False) -> Design | None:
        """The design submitted last: waited for while the designer makes progress; None if
        `stopped()` first. Raises GainDesignerLost if it has stalled or ended."""
        watch = self._watch
        if watch is not None:
            watch.begin()
        while not self._ended:
            try:
                if self._connection.poll(_LOOK_S):
                    return self._connection.recv()
            except (EOFError, OSError):
                self._ended = True
                break
            if stopped():
                return None
            if watch is not None and watch.extension_s() == 0.0 and self._process.is_alive():
                self._lost = _stall(self._process.pid, watch)
                raise GainDesignerLost(self._lost)
        self._process.join(timeout=1.0)
        self._lost = f"the gain designer's process ended (exit code {self._process.exitcode})"
        raise GainDesignerLost(self._lost)

    def pause(self, paused: bool) -> None:
        """Stop (SIGSTOP) or continue (SIGCONT) the designer where it is."""
        if paused != self._paused and self._process.pid is not None:
            with contextlib.suppress(ProcessLookupError):
                os.kill(self._process.pid, signal.SIGSTOP if paused else signal.SIGCONT)
            self._paused = paused

    def close(self) -> None:
        """Tell it to leave and wait a little; one that stalled, or does not leave, is killed
        (a stopped process keeps a SIGTERM pending, and multiprocessing would wait for it at
        this process's exit)."""
        process = self._process
        if self._lost is None and process.pid is not None:
            with contextlib.suppress(ProcessLookupError):  # stopped by whoever: it reads None
                os.kill(process.pid, signal.SIGCONT)
            self._paused = False
            with contextlib.suppress(OSError):  # (it may have ended already)
                self._connection.send(None)
            process.join(timeout=5.0)
        if process.is_alive():
            process.kill()
            process.join(timeout=5.0)
        self._connection.close()


def _stall(pid: int | None, watch: PeerWait) -> str:
    look = watch.last_look
    if look is not None and look.runnable:
        return (
            f"the gain designer (process {pid}) is still running after {watch.extended_s:.0f} s "
            "without a design (a design takes milliseconds)"
        )
    state = look.state if look is not None else "gone"
    return (
        f"the gain designer (process {pid}) has stalled: {state}, no progress for "
        f"{watch.idle_window_s:g} s"
    )


def _open_descriptors() -> set[int]:
    """This process's open file descriptors but the standard three (none known: empty)."""
    try:
        listed = {int(name) for name in os.listdir("/proc/self/fd")} - {0, 1, 2}
    except OSError:
        return set()
    return {fd for fd in listed if _is_open(fd)}  # not the one the listing itself used


def _is_open(fd: int) -> bool:
    try:
        os.fstat(fd)
    except OSError:
        return False
    return True


def _become_the_designer(host_pid: int, inherited: set[int]) -> None:
    """Tied to the loop's process and holding nothing of it (see the module docstring)."""
    with contextlib.suppress(OSError, AttributeError):  # (Linux only)
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
        libc.prctl(_PR_SET_NAME, ctypes.c_char_p(DESIGNER_PROCESS_NAME), 0, 0, 0)
    if os.getppid() != host_pid:  # the loop's process ended before the prctl took effect
        os._exit(1)
    for fd in inherited:
        with contextlib.suppress(OSError):
            os.close(fd)


def _serve(
    connection: Connection,
    robot: RobotModel,
    designer: Any,
    host_pid: int,
    inherited: set[int],
) -> None:
    """The designer process: one design per request, until None or the loop's end of the pipe
    closes. Ctrl-C is the loop's to handle (it closes the scheduler)."""
    _become_the_designer(host_pid, inherited)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    never_preempt_the_loop()
    with threadpool_limits(limits=1, user_api="blas"):
        while True:
            try:
                request = connection.recv()
            except (EOFError, OSError):
                return
            if request is None:
                return
            gain, compute_s = _design(robot, designer, *request)
            try:
                connection.send((gain, compute_s))
            except (pickle.PicklingError, TypeError, AttributeError):  # an exception that
                # cannot travel: its text does
                connection.send((RuntimeError(f"{type(gain).__name__}: {gain}"), compute_s))


def _design(
    robot: RobotModel, designer: Any, link_angle_rad: np.ndarray, contact: object
) -> Design:
    started = time.perf_counter()
    try:
        gain: TrackingGain | Exception = designer.design(robot.sm(link_angle_rad, contact))
    except Exception as exc:  # noqa: BLE001 - handed to the loop, raised there
        gain = exc
    return gain, time.perf_counter() - started


class _DesignThread:
    """The designs in a thread (where fork is not available): the same interface."""

    def __init__(self, robot: RobotModel, designer: Any) -> None:
        self._robot, self._designer = robot, designer
        self._request: tuple[np.ndarray, object] | None = None
        self._done: Design | None = None
        self._closed = False
        self._wake = threading.Condition()
        self._thread = threading.Thread(target=self._work, name="gain-scheduler", daemon=True)
        self._thread.start()

    def submit(self, link_angle_rad: np.ndarray, contact: object) -> None:
        with self._wake:
            self._request, self._done = (link_angle_rad, contact), None
            self._wake.notify()

    def done(self) -> bool:
        with self._wake:
            return self._done is not None

    def result(self, stopped: Callable[[], bool] = lambda: False) -> Design | None:
        with self._wake:
            while self._done is None and not self._closed:
                if stopped():
                    return None
                self._wake.wait(_LOOK_S)
            done, self._done = self._done, None
        return done if done is not None else (RuntimeError("the gain scheduler closed"), 0.0)

    def close(self) -> None:
        with self._wake:
            self._closed = True
            self._wake.notify_all()
        self._thread.join(timeout=5.0)

    def _work(self) -> None:
        while True:
            with self._wake:
                while self._request is None and not self._closed:
                    self._wake.wait()
                if self._closed:
                    return
                request, self._request = self._request, None
            done = _design(self._robot, self._designer, *request)
            with self._wake:
                self._done = done
                self._wake.notify_all()


class GainScheduler:
    """See the module docstring. `controller` must be an LQR controller (`set_lqr_gain`).

    wall_clock: install a design when it is done (else on its due tick, waiting for it).
    stop: the loop's StopFlag; a wait for a design ends when it is set."""

    def __init__(
        self,
        robot: RobotModel,
        controller: JointController,
        period_s: float,
        reschedule_s: float,
        *,
        wall_clock: bool,
        lead_ticks: int = LOCKSTEP_LEAD_TICKS,
        stop: StopFlag | None = None,
    ) -> None:
        self.robot = robot
        self.controller = controller
        self.period_s = period_s
        self.period_ticks = max(1, round(reschedule_s / period_s))
        self.wall_clock = wall_clock
        self.lead_ticks = max(1, int(lead_ticks))
        self._stop = stop
        self.schedule = GainSchedule()
        designer = controller.params.gain_designer(period_s)  # type: ignore[attr-defined]
        self._requested_contact: object = None
        self._last_request_tick: int | None = None
        self._pending: _Request | None = None  # handed to the worker, not yet installed
        self._tick_active = False  # (see tick_active)
        self._blas = threadpool_limits(limits=1, user_api="blas")
        fork = "fork" in multiprocessing.get_all_start_methods()
        self._worker = (_DesignProcess if fork else _DesignThread)(robot, designer)

    def update(
        self, tick: int, link_angle_rad: np.ndarray, contact: object, contact_ahead: object
    ) -> None:
        """Once per tick: install a design that is due (lock-step) or done (wall clock), and
        request one when due. `contact`: the LQR's contact now; `contact_ahead`: at tick +
        lead_ticks (lock-step; the wall clock passes the present one)."""
        if self._requested_contact is None:
            self._requested_contact = contact  # the controller was built for it
        self._install(tick)
        if self._pending is not None or np.count_nonzero(np.isfinite(link_angle_rad)) != len(
            link_angle_rad
        ):
            return
        wanted = contact if self.wall_clock else contact_ahead
        periodic = self._last_request_tick is None or (
            tick - self._last_request_tick >= self.period_ticks
        )
        if wanted == self._requested_contact and not periodic:
            return
        self._last_request_tick = tick
        self._requested_contact = wanted
        link = np.array(link_angle_rad, dtype=float)
        self._pending = _Request(link, wanted, time.perf_counter(), tick + self.lead_ticks)
        self._worker.submit(link, wanted)
        if self._tick_active:
            self.tick_active(True)  # it starts once the tick is over

    def tick_active(self, active: bool) -> None:
        """Wall clock: the loop starts (True) or has ended (False) the active part of its tick
        (the bus read, the compute, the write). A design in progress is stopped meanwhile and
        runs while the loop sleeps until its next tick. Beside the bus's answers a design every
        100 ms made the realtime humanoid's bus read p99 5.1-5.5 ms against 3.6-3.7 ms without;
        beside the compute it took the loop's CPU for a scheduler slice, ~6 ms ticks every
        100 ms on a slower day (docs/realtime.md). In lock-step nothing is stopped (its tick
        may wait for the design)."""
        self._tick_active = active
        if self.wall_clock and isinstance(self._worker, _DesignProcess):
            self._worker.pause(active and self._pending is not None)

    def close(self) -> None:
        self._worker.close()
        self._blas.restore_original_limits()

    def _stopped(self) -> bool:
        return self._stop is not None and self._stop.reason is not None

    def _install(self, tick: int) -> None:
        pending = self._pending
        if pending is None:
            return
        if self.wall_clock:
            if not self._worker.done():
                return
            done = self._worker.result()
        else:
            if tick < pending.due_tick:
                return
            started = time.perf_counter()
            try:
                done = self._worker.result(self._stopped)
            except GainDesignerLost as exc:
                raise GainDesignerLost(
                    f"{exc}, waiting for the design due at tick {tick} (t = "
                    f"{tick * self.period_s:.3f} s, requested at tick "
                    f"{pending.due_tick - self.lead_ticks}): the run stops"
                ) from None
            self.schedule.waited_s.append(time.perf_counter() - started)
        if done is None:  # stopped while waiting: the loop ends at its next tick
            return
        gain, compute_s = done
        self._pending = None
        if isinstance(gain, Exception):  # the design failed: say so on the loop's thread
            raise gain
        self.controller.set_lqr_gain(gain)  # type: ignore[attr-defined]
        self.schedule.designs += 1
        self.schedule.latencies_s.append(time.perf_counter() - pending.requested_s)
        self.schedule.compute_s.append(compute_s)
