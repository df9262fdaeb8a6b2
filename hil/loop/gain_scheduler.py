"""Rescheduling the LQR gain with posture and contact, off the 200 Hz path.

On the humanoid, Sm of (19) changes with the leg posture and with the LQR's contact (one sole or
both), and the LQR gain designed on it must follow (the lab's code recomputes it in a background
thread every 100 ms). A design runs in a worker thread, never inside a tick's compute:

    lock-step   a design is requested at tick k from the posture measured at k and installed
                at tick k + `lead_ticks` exactly (the tick waits for it only if it is not done
                by then): while the worker designs, the loop waits for the emulated robot, which
                steps in its own process. The gain in force at every tick depends on the run's
                samples only, never on timing: a lock-step run stays deterministic.
                The contact schedule is known ahead (the experiment's phases), so the design for
                a new contact is requested `lead_ticks` before it and installed on the tick it
                starts.
    wall clock  the same requests; a finished design is installed at the start of the first
                tick after it is done (a tick never waits for it).

Designs are requested every `period_ticks` and at every contact change (the doubling solver of
controller/lqr_designs.py: 1-6 ms for the lab's diagonal design, 5-30 ms for the closed chain on
the servo cascade on this machine), with one BLAS thread: on this 2-core machine a threaded BLAS
made a 36-state DARE take 138 ms instead of 52 ms (docs/walking.md), and a single-threaded
reduction is the same bits every run.
Each design's latency (request to use) and compute time are recorded for the summary.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field

import numpy as np
from threadpoolctl import threadpool_limits

from controller import JointController
from controller.lqr import TrackingGain
from hil.loop.robot_model import RobotModel

LOCKSTEP_LEAD_TICKS = 4  # a design requested at tick k is in force from tick k + 4 (20 ms)


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


class GainScheduler:
    """See the module docstring. `controller` must be an LQR controller (`set_lqr_gain`)."""

    def __init__(
        self,
        robot: RobotModel,
        controller: JointController,
        period_s: float,
        reschedule_s: float,
        *,
        threaded: bool,
        lead_ticks: int = LOCKSTEP_LEAD_TICKS,
    ) -> None:
        self.robot = robot
        self.controller = controller
        self.period_s = period_s
        self.period_ticks = max(1, round(reschedule_s / period_s))
        self.threaded = threaded  # wall clock: install when done; lock-step: on the due tick
        self.lead_ticks = max(1, int(lead_ticks))
        self.schedule = GainSchedule()
        self._designer = controller.params.gain_designer(period_s)  # type: ignore[attr-defined]
        self._requested_contact: object = None
        self._last_request_tick: int | None = None
        self._pending: _Request | None = None  # handed to the worker, not yet installed
        self._done: tuple[_Request, TrackingGain | Exception, float] | None = None
        self._wake = threading.Condition()
        self._closed = False
        self._blas = threadpool_limits(limits=1, user_api="blas")
        self._thread = threading.Thread(target=self._work, name="gain-scheduler", daemon=True)
        self._thread.start()

    def update(
        self, tick: int, link_angle_rad: np.ndarray, contact: object, contact_ahead: object
    ) -> None:
        """Once per tick: install a design that is due (lock-step) or done (wall clock), and
        request one when due. `contact`: the LQR's contact now; `contact_ahead`: at tick +
        lead_ticks (lock-step; the wall clock passes the present one)."""
        if self._requested_contact is None:
            self._requested_contact = contact  # the controller was built for it
        self._install(tick)
        if self._pending is not None or not np.isfinite(link_angle_rad).all():
            return
        wanted = contact_ahead if not self.threaded else contact
        periodic = self._last_request_tick is None or (
            tick - self._last_request_tick >= self.period_ticks
        )
        if wanted == self._requested_contact and not periodic:
            return
        self._last_request_tick = tick
        self._requested_contact = wanted
        request = _Request(
            np.array(link_angle_rad, dtype=float),
            wanted,
            time.perf_counter(),
            tick + self.lead_ticks,
        )
        with self._wake:
            self._pending = request
            self._wake.notify()

    def close(self) -> None:
        with self._wake:
            self._closed = True
            self._wake.notify()
        self._thread.join(timeout=5.0)
        self._blas.restore_original_limits()

    def _install(self, tick: int) -> None:
        pending = self._pending
        if pending is None:
            return
        if self.threaded:
            with self._wake:
                done = self._done
            if done is None:
                return
        else:
            if tick < pending.due_tick:
                return
            started = time.perf_counter()
            with self._wake:
                while self._done is None and not self._closed:
                    self._wake.wait()
                done = self._done
            self.schedule.waited_s.append(time.perf_counter() - started)
            if done is None:
                return
        with self._wake:
            self._done = None
            self._pending = None
        request, gain, compute_s = done
        if isinstance(gain, Exception):  # the design failed: say so on the loop's thread
            raise gain
        self.controller.set_lqr_gain(gain)  # type: ignore[attr-defined]
        self.schedule.designs += 1
        self.schedule.latencies_s.append(time.perf_counter() - request.requested_s)
        self.schedule.compute_s.append(compute_s)

    def _work(self) -> None:
        while True:
            with self._wake:
                while (self._pending is None or self._done is not None) and not self._closed:
                    self._wake.wait()
                if self._closed:
                    return
                request = self._pending
            assert request is not None
            started = time.perf_counter()
            gain: TrackingGain | Exception
            try:
                sm = self.robot.sm(request.link_angle_rad, request.contact)
                gain = self._designer.design(sm)
            except Exception as exc:  # noqa: BLE001 - handed to the loop, raised there
                gain = exc
            compute_s = time.perf_counter() - started
            with self._wake:
                self._done = (request, gain, compute_s)
                self._wake.notify_all()
