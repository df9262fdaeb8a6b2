"""The spine of every 200 Hz loop on this stack: the bus with the safety supervisor in front of
it, the torque, the clock's tick and the run's record (in the manner of vulp's Spine:
begin_cycle, cycle_actuation, end_cycle, around an explicit state).

    begin_cycle(tick)        read the bus once (a log in this process writes the last tick's
                             rows while the answers travel); on tick 0 the start gate
                             (hil/loop/start_gate.py) and torque on, holding the present
                             position; then every watch of the supervisor on the sample, and
                             torque off if one latched it (hil/loop/torque.py)
    cycle_actuation(goal)    the proposed goal (None: nothing proposed, the supervisor holds the
                             last one) through the supervisor to the bus; returns what was sent
    end_cycle(...)           the tick's record kept and handed to the log writer

`run(cycles)` opens the bus and says how the run ended when something raised (the start gate
refused, the bus was lost, an error), and `close()` is the common part of every exit path: the
last rows written, the supervisor's news logged, the configured exit torque state applied and
the bus closed. `hil run`'s experiments (hil/loop/runner.py) and a loop of your own
(hil/api.py) both go through it: one loop, not two.

Every tick reads the bus once, so in lock-step emulation tick k is the plant at k periods.
Tick 0 has no deadline: the wall clock's grid starts when it ends (`LoopClock.start_grid`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import can
import numpy as np

from drivers.joint_bus import BusError, JointBus, JointSample
from hil.config import Config
from hil.loop.clock import LoopClock, Tick
from hil.loop.run_record import RunRecord, SafetyNews
from hil.loop.start_gate import StartRefused, start_gate
from hil.loop.timeline import Phase
from hil.loop.torque import TorqueKeeper
from hil.output.log_process import LogProcess
from hil.output.runlog import RunLog
from hil.safety import Supervisor
from hil.vocabulary import RunEnding, Termination
from hil.wiring.hardware import configured_current_limits_a

# What a bus raises when it is lost: the JointBus contract says BusError, but a port that
# vanishes (USB unplugged, emulator gone) surfaces as python-can's or pyserial's own errors
# (serial.SerialException is an OSError).
LOST_BUS_ERRORS = (BusError, can.CanError, OSError)


@dataclass
class SpineState:
    """What the spine knows between and within cycles."""

    opened: bool = False  # the bus was opened: an exit path has something to turn off
    ticks_done: int = 0  # ticks completed (the next tick's index on a lock-step clock)
    ending: RunEnding = field(default_factory=lambda: RunEnding(Termination.COMPLETED))
    tick: Tick | None = None  # the cycle under way
    sample: JointSample | None = None  # its reading
    goal: np.ndarray | None = None  # what it sent (None: nothing)
    hold_goal: np.ndarray | None = None  # the present position at torque on
    last_goal: np.ndarray | None = None  # the last goal sent
    current_limits_a: np.ndarray | None = None
    # the cycle's times (perf_counter) and the last tick's rows' cost
    read_started: float = 0.0
    read_done: float = 0.0
    actuated: float = 0.0
    wait_log_s: float = 0.0
    log_s: float = 0.0


class Spine:
    """See the module docstring. `on_torque_on(sample)`: called on tick 0 once torque is on
    (the present position held); `check_settings(supervisor)`: on tick 0's watch, for settings
    only the caller knows (the DOB's Kdist); `overruns`: injected loop overruns (start, s)."""

    def __init__(
        self,
        config: Config,
        bus: JointBus,
        clock: LoopClock,
        supervisor: Supervisor,
        log: RunLog | LogProcess,
        record: RunRecord,
        *,
        reboot_first: bool = False,
        say: Callable[[str], None] | None = None,
        on_torque_on: Callable[[JointSample], None] | None = None,
        check_settings: Callable[[Supervisor], None] | None = None,
        overruns: Sequence[tuple[float, float]] = (),
    ) -> None:
        self.config = config
        self.bus = bus
        self.clock = clock
        self.period = clock.period_s
        self.supervisor = supervisor
        self.devices = bus.devices()
        self.log = log
        self.record = record
        self.news = SafetyNews(supervisor, log, say)
        self.torque = TorqueKeeper(bus, log.event)
        self.reboot_first = reboot_first
        self.on_torque_on = on_torque_on
        self.check_settings = check_settings
        self.overruns = tuple(overruns)
        self.state = SpineState()

    # --- the run's frame -------------------------------------------------------------------
    def run(self, cycles: Callable[[], None]) -> None:
        """Open the bus and run `cycles`; how the run ended if something raised (`ended_by`)."""
        try:
            self.open()
            cycles()
        except Exception as exc:
            if not self.ended_by(exc):
                raise

    def open(self) -> None:
        self.bus.open()
        self.state.opened = True
        self.log.event(0.0, "open", f"bus open: {', '.join(self.config.joint_names)}")

    def ended_by(self, exc: Exception) -> bool:
        """The run ended by `exc`: said and recorded; True when that is an ending of the run
        (the start gate refused, the bus was lost), False for an error (to be re-raised)."""
        state = self.state
        if isinstance(exc, StartRefused):
            state.ending = RunEnding(Termination.START_REFUSED, str(exc))
            self.log.event(0.0, "start_refused", str(exc))
            return True
        if isinstance(exc, LOST_BUS_ERRORS):
            state.ending = RunEnding(Termination.BUS_FAILURE, str(exc))
            self.log.event(self.now_s, "bus_failure", f"{type(exc).__name__}: {exc}")
            return True
        state.ending = RunEnding(Termination.ERROR, f"{type(exc).__name__}: {exc}")
        self.log.event(self.now_s, "error", state.ending.text)
        return False

    @property
    def now_s(self) -> float:
        return self.state.ticks_done * self.period

    @property
    def started(self) -> bool:
        """Torque has been turned on (tick 0 is behind)."""
        return self.state.hold_goal is not None

    # --- one cycle ---------------------------------------------------------------------------
    def begin_cycle(self, tick: Tick) -> JointSample:
        """Read the bus, start on tick 0, run the supervisor's watches; the tick's sample."""
        state = self.state
        state.tick, state.goal = tick, None
        state.read_started = time.perf_counter()
        self.bus.start_read()
        try:  # the last tick's rows, while the answers travel
            state.wait_log_s = self.record.write_in_wait()
        finally:  # whatever happened, the answers are collected: no transaction left open
            sample = self.bus.finish_read()
        state.read_done = time.perf_counter()
        state.log_s = self.record.log_s(state.wait_log_s)
        if tick.index == 0:
            sample = self._start(sample)
        self._watch(tick, sample)
        state.sample = sample
        return sample

    def cycle_actuation(self, proposed: np.ndarray | None) -> np.ndarray | None:
        """The proposed goal through the supervisor to the bus; what was sent (None: nothing:
        torque is off, or nothing is known to hold)."""
        state = self.state
        assert state.sample is not None, "begin_cycle() first"
        goal = self.supervisor.command(proposed, state.sample) if self.torque.on else None
        if goal is not None:
            self.bus.write(goal)
            state.last_goal = goal
        state.goal = goal
        self.news.log_new()
        state.actuated = time.perf_counter()
        return goal

    def end_cycle(
        self, reference: np.ndarray, phase: Phase, terms: Mapping[str, np.ndarray] | None
    ) -> None:
        """The tick's record kept (`reference`: what the goal followed; `terms`: the
        controller's, None before it stepped) and handed to the log writer."""
        state = self.state
        tick, sample = state.tick, state.sample
        assert tick is not None and sample is not None, "begin_cycle() first"
        k = tick.index
        timing = (
            k,
            state.read_done - state.read_started - state.wait_log_s,
            state.actuated - state.read_done,
            0.0,
            state.log_s,
            tick.time_s,
        )
        self.record.keep(
            tick, sample, reference, state.goal, phase, self.supervisor.state, terms, timing
        )
        # the tick is done once its rows are the record's: a writer found lost at the hand-over
        # keeps them too (the loop writes them), and summary.json's ticks counts them
        state.ticks_done = k + 1
        if k == 0:  # the start-up tick is not paced (hil/loop/clock.py)
            self.clock.start_grid()
        self.record.hand_over()

    # --- tick 0 --------------------------------------------------------------------------------
    def _start(self, sample: JointSample) -> JointSample:
        config = self.config
        sample = start_gate(
            config, sample, self.bus, self.devices, self.reboot_first, self.log.event
        )
        reported = np.asarray(self.bus.current_limits_a(), dtype=float)
        configured = np.array(configured_current_limits_a(config))
        limits = np.where(np.isfinite(reported), reported, configured)
        self.state.current_limits_a = limits
        self.supervisor.set_current_limits(limits)
        if config.safety.current_guard and not np.isfinite(limits).all():
            self.log.event(
                0.0,
                "current_guard_inactive",
                "the software overload guard cannot act: an actuator's current limit is "
                "unknown (set torque_limit_a in the configuration)",
            )
        self.torque.enable()
        self.state.hold_goal = sample.motor_angle_rad.copy()
        self.state.last_goal = self.state.hold_goal.copy()
        self.log.event(0.0, "torque_on", "torque on; holding the present position")
        if self.on_torque_on is not None:
            self.on_torque_on(sample)
        return sample

    # --- each tick -----------------------------------------------------------------------------
    def _watch(self, tick: Tick, sample: JointSample) -> None:
        k, time_s = tick.index, tick.time_s
        supervisor = self.supervisor
        overrun = self._injected_overrun(time_s)
        if tick.skipped or overrun:
            supervisor.note_overrun(k, time_s, tick.skipped)
        for note in sample.notes:
            self.log.event(time_s, "bus_note", note, tick=k)
        supervisor.observe(k, time_s, sample)
        self.news.log_new()
        if k == 0:  # this tick's sample predates the enable: expect torque from the next one on
            assert self.state.hold_goal is not None
            supervisor.torque_enabled(self.state.hold_goal)
            if self.check_settings is not None:
                self.check_settings(supervisor)
                self.news.log_new()
        self.torque.off_if_latched(k, time_s, sample, supervisor)

    def _injected_overrun(self, time_s: float) -> bool:
        for start, duration in self.overruns:
            if start <= time_s < start + max(duration, self.period):
                if not self.clock.deterministic:
                    time.sleep(self.period * 1.5)  # really miss the deadline
                return True
        return False

    # --- every exit path -----------------------------------------------------------------------
    def close(self) -> list[str]:
        """The common part of every exit path: the supervisor's news logged, the configured exit
        torque state, the bus closed; the notes for summary.json. (The caller writes the last
        kept rows first, so that a lost writer can change the run's ending.)"""
        self.news.log_new()
        return self.torque.exit_state(self.config.safety.on_exit, self.now_s, self.state.opened)

    def safety_summary(self) -> dict[str, object]:
        """What the supervisor did, for summary.json."""
        supervisor = self.supervisor
        return {
            "safety_events": [e.record() for e in supervisor.events],
            "safety_notices": [n.record() for n in supervisor.notices],
            "safety_counters": supervisor.counters(),
        }

    @property
    def current_limits(self) -> list[float]:
        limits = self.state.current_limits_a
        n = len(self.config.joints)
        return (limits if limits is not None else np.full(n, math.nan)).tolist()
