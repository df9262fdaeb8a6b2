"""The run's record as the loop keeps it: each tick's rows, and the supervisor's news.

A tick's log.csv and timing.csv rows are kept (`keep`: nothing it keeps is changed in place
later). The log writer's process gets them at the end of the tick (~20 us for the humanoid's
~220 numbers). A log in this process (the live view) writes them during the next tick, between
sending the bus requests and collecting the answers: formatting them costs ~0.3-0.4 ms on the
humanoid, time the answers spend travelling anyway; the last tick's rows are written on every
exit path (`write_kept`), and a process killed outright loses them. Neither way waits: a log
writer that is lost raises from the hand-over (the spine counts the tick done first: its rows
are kept and written by the loop at the end), and a disk that refuses a row raises from the
write during the wait (hil/output/record_files.py).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence

import numpy as np

from drivers.joint_bus import JointSample
from hil.loop.clock import Tick
from hil.loop.timeline import Phase
from hil.output.log_process import LogProcess
from hil.output.runlog import RunLog
from hil.safety import SafeState, Supervisor

_STATE_NAMES = {state: state.name.lower() for state in SafeState}  # as log.csv writes them

Timing = tuple[int, float, float, float, float, float]  # tick, read, compute, write, log, time


class RunRecord:
    """The tick's rows on their way to the run's log (see the module docstring)."""

    def __init__(
        self,
        log: RunLog | LogProcess,
        sensor_columns: Sequence[str],
        term_names: Sequence[str],
        n_joints: int,
    ) -> None:
        self.log = log
        self.sensor_columns = tuple(sensor_columns)
        self.term_names = tuple(term_names)
        # Formatting the rows here: during the next tick's bus wait. The log writer's process
        # formats them: handed over at the end of their own tick.
        self.rows_in_wait = isinstance(log, RunLog)
        self._kept: tuple[tuple, Timing] | None = None  # the last tick's rows, not yet written
        self.handed_over_s = 0.0  # how long handing the last tick's rows over took
        self._zeros = np.zeros(n_joints)
        self._no_goal = np.full(n_joints, math.nan)  # logged on ticks that send nothing

    def keep(
        self,
        tick: Tick,
        sample: JointSample,
        reference: np.ndarray,
        goal: np.ndarray | None,
        phase: Phase,
        state: SafeState,
        terms: Mapping[str, np.ndarray] | None,
        timing: Timing,
    ) -> None:
        """This tick's rows (terms None: the controller has not stepped yet, zeros)."""
        zeros = self._zeros
        extra = sample.extra
        sensors = [extra.get(name, math.nan) for name in self.sensor_columns]
        row = (
            tick.index,
            tick.time_s,
            sensors,
            _STATE_NAMES[state],
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
                    (terms.get(name, self._no_goal) for name in self.term_names)
                    if terms is not None
                    else (zeros for _ in self.term_names)
                ),
            ),
            tick.slack_s,
            tick.measured_period_s,
        )
        self._kept = (row, timing)

    def write_kept(self) -> float:
        """Write the kept rows (if any); returns the seconds it took."""
        kept, self._kept = self._kept, None
        if kept is None:
            return 0.0
        started = time.perf_counter()
        self.log.write_tick(*kept)
        return time.perf_counter() - started

    def write_in_wait(self) -> float:
        """While the bus's answers travel: the last tick's rows, for a log in this process."""
        return self.write_kept() if self.rows_in_wait else 0.0

    def hand_over(self) -> None:
        """At the end of the tick: the rows to the log writer's process (nothing to lose)."""
        if not self.rows_in_wait:
            self.handed_over_s = self.write_kept()

    def log_s(self, wait_log_s: float) -> float:
        """What the last tick's rows cost this tick (timing.csv's log_s)."""
        return wait_log_s if self.rows_in_wait else self.handed_over_s


class SafetyNews:
    """The supervisor's new events and notices, to events.jsonl (and said, if asked)."""

    def __init__(
        self, supervisor: Supervisor, log: RunLog | LogProcess, say: Callable[[str], None] | None
    ) -> None:
        self.supervisor = supervisor
        self.log = log
        self.say = say
        self._events = self._notices = 0

    def log_new(self) -> None:
        supervisor = self.supervisor
        for event in supervisor.events[self._events :]:
            self.log.event(
                event.time_s,
                str(event.cause),
                event.message,
                joint=event.joint,
                action=str(event.action),
                state=event.state,
                tick=event.tick,
            )
            if self.say is not None:
                self.say(
                    f"  [{event.time_s:7.3f} s] {event.cause} -> {event.action}: {event.message}"
                )
        for notice in supervisor.notices[self._notices :]:
            self.log.event(
                notice.time_s,
                str(notice.kind),
                notice.message,
                joint=notice.joint,
                tick=notice.tick,
            )
        self._events, self._notices = len(supervisor.events), len(supervisor.notices)
