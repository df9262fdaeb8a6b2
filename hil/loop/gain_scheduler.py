"""Rescheduling the LQR gain with posture and support, off the 200 Hz path.

On the humanoid, Sm of (19) changes with the leg posture and with the support foot, and the
LQR gain designed on it must follow (the lab's code recomputes it in a background thread every
100 ms). Designing a 12-joint gain takes tens of milliseconds: never inside a tick.

    wall clock  a worker thread designs the gain from the latest (posture, support) it was
                handed; the loop hands it a new one when it is idle and picks up a finished
                gain at the start of a tick (`update`): a tick never waits for it
    lock-step   the same design, done in the tick every `period_ticks` ticks and on a support
                change (the simulated plant waits, so the run stays deterministic)
Each design's latency (request to use) is recorded for the summary.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field

import numpy as np

from controller import JointController
from controller.lqr import TrackingGain
from hil.loop.robot_model import RobotModel


@dataclass
class _Request:
    link_angle_rad: np.ndarray
    support: object
    requested_s: float


@dataclass
class GainSchedule:
    """What the scheduler did: designs used, their latency (request to use) [s]."""

    designs: int = 0
    latencies_s: list[float] = field(default_factory=list)

    def record(self) -> dict[str, object]:
        latency = np.asarray(self.latencies_s)
        return {
            "designs": self.designs,
            "latency_median_s": float(np.median(latency)) if latency.size else None,
            "latency_max_s": float(latency.max()) if latency.size else None,
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
    ) -> None:
        self.robot = robot
        self.controller = controller
        self.period_s = period_s
        self.period_ticks = max(1, round(reschedule_s / period_s))
        self.threaded = threaded
        self.schedule = GainSchedule()
        self._support: object = None
        self._last_tick = -self.period_ticks
        self._pending: _Request | None = None
        self._done: tuple[TrackingGain, float] | None = None
        self._wake = threading.Condition()
        self._closed = False
        self._thread: threading.Thread | None = None
        if threaded:
            self._thread = threading.Thread(target=self._work, name="gain-scheduler", daemon=True)
            self._thread.start()

    def update(self, tick: int, link_angle_rad: np.ndarray, support: object) -> None:
        """Once per tick (cheap): use a finished design, ask for a new one when due."""
        changed = support != self._support
        self._support = support
        if self.threaded:
            self._pick_up()
        due = changed or tick - self._last_tick >= self.period_ticks
        if not due or not np.isfinite(link_angle_rad).all():
            return
        self._last_tick = tick
        request = _Request(np.array(link_angle_rad, dtype=float), support, time.perf_counter())
        if self.threaded:
            with self._wake:
                self._pending = request  # the newest posture replaces an unstarted one
                self._wake.notify()
        else:
            self._use(self._design(request), request.requested_s)

    def close(self) -> None:
        with self._wake:
            self._closed = True
            self._wake.notify()
        if self._thread is not None:
            self._thread.join(timeout=5.0)

    def _design(self, request: _Request) -> TrackingGain:
        sm = self.robot.sm(request.link_angle_rad, request.support)
        return self.controller.params.design_gain(sm, self.period_s)  # type: ignore[attr-defined]

    def _use(self, gain: TrackingGain, requested_s: float) -> None:
        self.controller.set_lqr_gain(gain)  # type: ignore[attr-defined]
        self.schedule.designs += 1
        self.schedule.latencies_s.append(time.perf_counter() - requested_s)

    def _pick_up(self) -> None:
        with self._wake:
            done, self._done = self._done, None
        if done is not None:
            self._use(*done)

    def _work(self) -> None:
        while True:
            with self._wake:
                while self._pending is None and not self._closed:
                    self._wake.wait()
                if self._closed:
                    return
                request, self._pending = self._pending, None
            gain = self._design(request)
            with self._wake:
                self._done = (gain, request.requested_s)
