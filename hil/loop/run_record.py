"""The run's record, kept and written each tick (a mixin of `hil.loop.runner.Loop`).

A tick's log.csv and timing.csv rows are kept (`_keep_record`: nothing it keeps is changed
in place later). The log writer's process gets them at the end of the tick (~20 us for
the humanoid's ~220 numbers). A log in this process (the live view) writes them during
the next tick, between sending the bus requests and collecting the answers: formatting
them costs ~0.3-0.4 ms on the humanoid, time the answers spend travelling anyway; the
last tick's rows are written by `_finish` on every exit path, and a process killed
outright loses them.
"""

from __future__ import annotations

import math
import time

import numpy as np

from drivers.joint_bus import JointSample
from hil.loop.clock import Tick
from hil.loop.timeline import Phase
from hil.safety import SafeState

_STATE_NAMES = {state: state.name.lower() for state in SafeState}  # as log.csv writes them


class RunRecording:
    """`_keep_record` at the end of a tick, `_write_kept_record` where the loop has time for it,
    `_log_safety` for the supervisor's news."""

    def _keep_record(
        self,
        tick: Tick,
        sample: JointSample,
        reference: np.ndarray,
        goal: np.ndarray | None,
        phase: Phase,
        timing: tuple[int, float, float, float, float, float],
    ) -> None:
        terms = self.controller.terms() if self._controller_started else None
        zeros = self._zeros
        extra = sample.extra
        sensors = [extra.get(name, math.nan) for name in self.sensor_columns]
        row = (
            tick.index,
            tick.time_s,
            sensors,
            _STATE_NAMES[self.supervisor.state],
            phase.value,
            tick.skipped,
            (
                reference,  # rows of the run's reference table, which does not change
                goal if goal is not None else self._no_goal,  # the supervisor's own copy
                sample.motor_angle_rad,  # a sample's arrays are the bus's new ones every read
                sample.link_angle_rad,
                sample.link_angle_rad - sample.motor_angle_rad,
                sample.motor_velocity_rad_s,
                sample.motor_current_a,
                sample.actuator_fault,
                sample.torque_enabled,
                sample.motor_valid,
                sample.link_valid,
                sample.link_age_s,
                *(
                    (terms[name] for name in self.term_names)  # copies: the contract's
                    if terms is not None
                    else (zeros for _ in self.term_names)
                ),
            ),
            tick.slack_s,
            tick.measured_period_s,
        )
        self._kept = (row, timing)

    def _write_kept_record(self) -> float:
        """Write the kept rows (if any); returns the seconds it took."""
        kept, self._kept = self._kept, None
        if kept is None:
            return 0.0
        started = time.perf_counter()
        self.log.write_tick(*kept)
        return time.perf_counter() - started

    def _log_safety(self) -> None:
        """Write the supervisor's new events and notices to events.jsonl (and say them)."""
        supervisor = self.supervisor
        for event in supervisor.events[self._logged_events :]:
            self.log.event(
                event.time_s,
                str(event.cause),
                event.message,
                joint=event.joint,
                action=str(event.action),
                state=event.state,
                tick=event.tick,
            )
            if self.request.on_event is not None:
                self.request.on_event(
                    f"  [{event.time_s:7.3f} s] {event.cause} -> {event.action}: {event.message}"
                )
        for notice in supervisor.notices[self._logged_notices :]:
            self.log.event(
                notice.time_s,
                str(notice.kind),
                notice.message,
                joint=notice.joint,
                tick=notice.tick,
            )
        self._logged_events, self._logged_notices = len(supervisor.events), len(supervisor.notices)
