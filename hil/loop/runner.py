"""One run of an experiment: the 200 Hz loop from bus to controller to bus, and every exit path.

Each cycle is `read -> watch -> propose -> shape -> write -> log` (in the manner of vulp's
Spine: begin_cycle, cycle_actuation, end_cycle), and what `propose` does depends on the phase
(hil/loop/timeline.py):
    tick 0      read; the start gate (hil/loop/start_gate.py); torque on (goal = present);
                plan the re-homing if the link starts away from the experiment's start
    HOLD        hold the present position
    HOMING      the slow ramp, followed by the actuator's own position servo
    EXPERIMENT  the controller along the experiment's reference (it starts bumplessly from the
                goal in force; it is not stepped while the supervisor holds a safe state; an
                experiment with a `ReferenceFeedback` corrects the reference from the tick's
                measured link angles first, and the log records the corrected one), or,
                for an open-loop experiment (identification), the goal in force at its start
                plus the experiment's own goal offsets, with no controller
    STOP        hold the last goal; then the configured exit torque state
Every tick reads the bus once, so in lock-step emulation tick k is the plant at k periods.
Tick 0 has no deadline: the wall clock's grid starts when it ends (`LoopClock.start_grid`).

When the supervisor latches torque_off, the loop turns torque off at once; if the bus does not
take it (a silent device), it tries again every DISABLE_RETRY_TICKS ticks, not every tick (each
try costs the driver's timeouts), and on the tick the actuators answer again.

Every exit path - the end, Ctrl-C, SIGTERM, an exception in the controller or the bus - goes
through the same `finally`: the configured exit torque state is applied (best effort on every
joint, whatever the bus raises), the bus is closed, summary.json is written, and the log files
are closed. The log is written by a process of its own (hil/output/log_process.py), which has
every tick's rows at the end of that tick and writes what it has when this process ends, however
it ends; a writer that ends before the run stops the run like a lost bus. With the live view the
log stays in this process, line-buffered, a tick's rows written during the next tick (see
`_keep_record`).
"""

from __future__ import annotations

import gc
import math
import time
from dataclasses import dataclass
from typing import Any

import can
import numpy as np

from controller import JointController
from drivers.joint_bus import BusError, JointBus, JointDevices, JointSample, wrench_keys
from hil.config import Config
from hil.experiments import Experiment
from hil.loop.clock import LoopClock, Tick
from hil.loop.controller_factory import build_controller, joint_params
from hil.loop.experiment_feed import ExperimentFeed
from hil.loop.gain_scheduler import GainScheduler
from hil.loop.homing import HomingPlan, plan_homing
from hil.loop.request import RunRequest, StopFlag
from hil.loop.robot_model import robot_model
from hil.loop.run_end import RunEnd
from hil.loop.run_record import RunRecording
from hil.loop.start_gate import StartRefused, start_gate
from hil.loop.timeline import Phase, Timeline
from hil.output.log_process import open_run_log
from hil.output.records import RunResult
from hil.output.runlog import RunLog
from hil.safety import SafeState, Supervisor
from hil.vocabulary import RunEnding, Termination
from hil.wiring.hardware import configured_current_limits_a

DISABLE_RETRY_TICKS = 20  # a torque off the bus did not take is tried again this often
# The reference is computed this many ticks ahead (60 s: all of a usual experiment at tick 0),
# then one tick at a time in a ring of this many rows: a run's memory does not grow with its
# planned duration, and no later tick computes more than the rows the clock skipped.
REFERENCE_AHEAD_TICKS = 12_000
# What a bus raises when it is lost: the JointBus contract says BusError, but a port that
# vanishes (USB unplugged, emulator gone) surfaces as python-can's or pyserial's own errors
# (serial.SerialException is an OSError).
LOST_BUS_ERRORS = (BusError, can.CanError, OSError)


@dataclass
class _TorqueState:
    """What the loop knows of the actuators' torque and of its tries to turn it off."""

    on: bool = False
    retry_tick: int = 0
    failures: int = 0
    answered_before: bool = True


def _supervisor(config: Config, devices: JointDevices, period_s: float) -> Supervisor:
    """The safety supervisor of the configured joints (limits, stiffness, `[safety]`)."""
    return Supervisor(
        config.safety,
        config.joint_names,
        devices,
        np.array([j.min_angle_rad for j in config.joints]),
        np.array([j.max_angle_rad for j in config.joints]),
        period_s,
        joint_params(config).stiffness_nm_per_rad,
    )


class Loop(ExperimentFeed, RunRecording, RunEnd):
    """One run; `run()` returns its result. See the module docstring."""

    def __init__(
        self,
        config: Config,
        request: RunRequest,
        bus: JointBus,
        clock: LoopClock,
        meta: dict[str, Any],
        stop: StopFlag,
    ) -> None:
        self.config = config
        self.request = request
        self.experiment: Experiment = request.experiment
        self.bus = bus
        self.clock = clock
        self.stop = stop
        self.period = clock.period_s
        n = len(config.joints)
        self.n = n
        self.devices = bus.devices()
        self.supervisor = _supervisor(config, self.devices, self.period)
        low, high = self.experiment.reference_range(n)
        self.supervisor.check_reference(low, high)
        self.robot = robot_model(config)
        self._lqr_contacts = self._lqr_contact_table(request.run_duration_s)
        self.controller: JointController = build_controller(
            config,
            request.choice,
            self.period,
            self.robot,
            np.broadcast_to(self.experiment.reference(0.0), (n,)),
            self._lqr_contacts[0],
        )
        self.scheduler: GainScheduler | None = None
        if self.robot.rescheduled and request.choice.kind.has_lqr:
            self.scheduler = GainScheduler(
                self.robot,
                self.controller,
                self.period,
                config.model.gain_reschedule_period_s,
                wall_clock=not clock.deterministic,
                stop=stop,
            )
        self._support: object = None
        self._kdist: np.ndarray | None = None
        self.timeline = Timeline.plan(self.period, config.loop.stop_cycles, request.run_duration_s)
        self.sensor_columns = sensor_columns(config)
        self._open_loop = self._open_loop_offsets(config.safety.max_goal_rate_rad_s)
        self.feedback = None if self._open_loop is not None else self._reference_feedback()
        self._goal_base: np.ndarray | None = None  # an open-loop experiment's goals start here
        self.log = open_run_log(
            request.out_dir,
            config.joint_names,
            meta,
            self.sensor_columns,
            mcap=request.mcap,
            sinks=request.sinks,
        )
        # Formatting the rows here: during the next tick's bus wait. The log writer's process
        # formats them: handed over at the end of their own tick (see `_write_kept_record`).
        self._rows_in_wait = isinstance(self.log, RunLog)
        self._kept: tuple[tuple, tuple] | None = None  # the last tick's rows, not yet written
        self._handed_over_s = 0.0  # how long handing the last tick's rows over took
        self.homing: HomingPlan | None = None
        self.references = np.zeros((0, n))  # a ring: tick k's row is at k % len
        self._reference_filled = 0  # the first tick whose row is not in the ring yet
        self.torque = _TorqueState()
        self.current_limits = np.full(n, math.nan)
        self.ending = RunEnding(Termination.COMPLETED)
        self.opened = False
        self.torque_off_failed = False  # the exit path's torque off was not taken
        self.ticks_done = 0
        self._hold_goal = np.full(n, math.nan)
        self._last_goal = np.full(n, math.nan)
        self._last_link = np.full(n, math.nan)
        self._no_goal = np.full(n, math.nan)  # logged on ticks that send nothing
        self._zeros = np.zeros(n)
        self._controller_started = False
        self._last_step_tick = -1
        self._logged_events = self._logged_notices = 0

    # --- the run -------------------------------------------------------------------------------
    def run(self) -> RunResult:
        started = time.perf_counter()
        try:
            self.bus.open()
            self.opened = True
            self.log.event(0.0, "open", f"bus open: {', '.join(self.config.joint_names)}")
            self._cycles()
        except StartRefused as exc:
            self.ending = RunEnding(Termination.START_REFUSED, str(exc))
            self.log.event(0.0, "start_refused", str(exc))
        except LOST_BUS_ERRORS as exc:
            self.ending = RunEnding(Termination.BUS_FAILURE, str(exc))
            self.log.event(self._now(), "bus_failure", f"{type(exc).__name__}: {exc}")
        except Exception as exc:
            self.ending = RunEnding(Termination.ERROR, f"{type(exc).__name__}: {exc}")
            self.log.event(self._now(), "error", self.ending.text)
            raise
        finally:
            self._finish(time.perf_counter() - started)
        return self.result

    def _cycles(self) -> None:
        # No garbage collection on the tick path: what exists now is frozen out of the
        # collector's reach and the collector waits for the end of the run (the tick allocates
        # little, and nothing that forms cycles).
        gc.collect()
        gc.freeze()
        gc.disable()
        try:
            self._ticks()
        finally:
            gc.enable()
            gc.unfreeze()

    def _ticks(self) -> None:
        while self.ticks_done < self.timeline.end:
            if self.stop.reason is not None:
                self.ending = RunEnding(Termination.INTERRUPTED, self.stop.reason)
                return
            tick = self.clock.next_tick()
            # The clock's grid index: after a missed deadline the wall clock skips ticks, and the
            # reference, the faults and the log follow the grid, not the loop's count.
            if tick.index >= self.timeline.end:
                break
            self._cycle(tick)
            self.ticks_done = tick.index + 1
            if tick.index == 0:  # the start-up tick is not paced (hil/loop/clock.py)
                self.clock.start_grid()
        first = self.supervisor.first_trip
        if first is not None:
            self.ending = RunEnding(Termination.SAFETY_STOP, f"{first.cause} ({first.action})")

    def _cycle(self, tick: Tick) -> None:
        scheduler = self.scheduler
        if scheduler is None:
            self._active_cycle(tick)
            return
        scheduler.tick_active(True)
        try:
            self._active_cycle(tick)
        finally:
            scheduler.tick_active(False)

    def _active_cycle(self, tick: Tick) -> None:
        k = tick.index
        t_read = time.perf_counter()
        self.bus.start_read()
        try:  # the last tick's rows, while the answers travel
            wait_log_s = self._write_kept_record() if self._rows_in_wait else 0.0
        finally:  # whatever happened, the answers are collected: no transaction left open
            sample = self.bus.finish_read()
        t_compute = time.perf_counter()
        log_s = wait_log_s if self._rows_in_wait else self._handed_over_s
        if k == 0:
            sample = self._start(sample)
        self._watch(tick, sample)
        if k >= self._reference_filled:  # (the clock skipped more ticks than the ring holds)
            self._reference_ahead(k - 1)
        proposed, reference = self._propose(k, sample, self.references[k % len(self.references)])
        goal = self.supervisor.command(proposed, sample) if self.torque.on else None
        phase = self.timeline.phase(k)
        if proposed is not None and phase is Phase.EXPERIMENT and self._controller_started:
            self.controller.notify_applied(goal if goal is not None else proposed)
        if goal is not None:
            self.bus.write(goal)
            self._last_goal = goal
        self._log_safety()
        t_done = time.perf_counter()
        timing = (k, t_compute - t_read - wait_log_s, t_done - t_compute, 0.0, log_s, tick.time_s)
        self._keep_record(tick, sample, reference, goal, phase, timing)
        if not self._rows_in_wait:  # the writer's process has them now: nothing to lose
            self._handed_over_s = self._write_kept_record()
        self._reference_ahead(k)
        on_progress = self.request.on_progress
        if on_progress is not None and k % int(round(1.0 / self.period)) == 0:
            on_progress(tick.time_s, self.timeline.end * self.period)

    # --- tick 0 ------------------------------------------------------------------------------
    def _start(self, sample: JointSample) -> JointSample:
        sample = start_gate(
            self.config, sample, self.bus, self.devices, self.request.reboot_first, self.log.event
        )
        reported = np.asarray(self.bus.current_limits_a(), dtype=float)
        configured = np.array(configured_current_limits_a(self.config))
        self.current_limits = np.where(np.isfinite(reported), reported, configured)
        self.supervisor.set_current_limits(self.current_limits)
        if self.config.safety.current_guard and not np.isfinite(self.current_limits).all():
            self.log.event(
                0.0,
                "current_guard_inactive",
                "the software overload guard cannot act: an actuator's current limit is "
                "unknown (set torque_limit_a in the configuration)",
            )
        self.bus.enable()
        self.torque.on = True
        self._hold_goal = sample.motor_angle_rad.copy()
        self._last_goal = self._hold_goal.copy()
        self.log.event(0.0, "torque_on", "torque on; holding the present position")
        start = np.broadcast_to(self.experiment.reference(0.0), (self.n,))
        self.homing = plan_homing(sample.link_angle_rad, start)
        if self.homing is not None:
            self.timeline = self.timeline.with_homing(self.homing.ticks(self.period))
            self.log.event(0.0, "homing", self.homing.describe())
        ahead = min(self.timeline.end, REFERENCE_AHEAD_TICKS)
        self.references = np.empty((ahead, self.n))
        self._reference_filled = 0
        self._reference_ahead(-1)
        if self.feedback is not None:
            self.log.event(0.0, "reference_feedback", self.feedback.describe())
        return sample

    # --- each tick ---------------------------------------------------------------------------
    def _watch(self, tick: Tick, sample: JointSample) -> None:
        k, time_s = tick.index, tick.time_s
        overrun = self._injected_overrun(time_s)
        if tick.skipped or overrun:
            self.supervisor.note_overrun(k, time_s, tick.skipped)
        for note in sample.notes:
            self.log.event(time_s, "bus_note", note, tick=k)
        self.supervisor.observe(k, time_s, sample)
        self._log_safety()
        if k == 0:  # this tick's sample predates the enable: expect torque from the next one on
            self.supervisor.torque_enabled(self._hold_goal)
            if self.request.choice.kind.has_dob:
                self.supervisor.check_settings(self.request.choice.kdist)
                self._log_safety()
        self._torque_off_if_latched(k, time_s, sample)

    def _torque_off_if_latched(self, k: int, time_s: float, sample: JointSample) -> None:
        torque = self.torque
        answered = bool(sample.motor_valid.all())
        due = k >= torque.retry_tick or (answered and not torque.answered_before)
        if self.supervisor.state == SafeState.TORQUE_OFF and torque.on and due:
            why = "safety stop" + (f" (try {torque.failures + 1})" if torque.failures else "")
            torque.on = not self._disable(time_s, why, quiet=torque.failures > 0)
            self.supervisor.torque_disabled()
            if torque.on:
                torque.failures += 1
                torque.retry_tick = k + DISABLE_RETRY_TICKS
        torque.answered_before = answered

    def _propose(
        self, k: int, sample: JointSample, reference: np.ndarray
    ) -> tuple[np.ndarray | None, np.ndarray]:
        """The goal this phase proposes (None: the controller cannot step this tick), and the
        reference it followed (the table's, or as the experiment's feedback corrected it)."""
        link = np.where(sample.link_valid, sample.link_angle_rad, self._last_link)
        self._last_link = link
        phase = self.timeline.phase(k)
        if phase is Phase.STOP:
            return self._last_goal, reference
        if phase is Phase.HOLD:
            return self._hold_goal, reference
        if phase is Phase.HOMING:
            return reference, reference  # the actuator's own servo follows the ramp
        n = self.n
        if (
            self.supervisor.safe
            or np.count_nonzero(sample.motor_valid) != n
            or np.count_nonzero(np.isfinite(link)) != n
        ):
            return None, reference
        if self._open_loop is not None:
            return self._open_loop_goal(k), reference
        self._schedule(k, link)
        if self.feedback is not None:
            time_s = self.timeline.experiment_time_s(k)
            reference = self.feedback.reference(time_s, reference, link, sample.motor_angle_rad)
        controller = self.controller
        if not self._controller_started:  # bumpless: from the goal the servo is driven with
            controller.reset(sample.motor_angle_rad, link, reference, self._last_goal)
            self._controller_started = True
        elif k - self._last_step_tick > 1:  # ticks without a step: do not read them as motion
            controller.resync(sample.motor_angle_rad, link)
        self._last_step_tick = k
        return controller.step(sample.motor_angle_rad, link, reference), reference

    def _injected_overrun(self, time_s: float) -> bool:
        for start, duration in self.request.overruns:
            if start <= time_s < start + max(duration, self.period):
                if not self.clock.deterministic:
                    time.sleep(self.period * 1.5)  # really miss the deadline
                return True
        return False

    def _now(self) -> float:
        return self.ticks_done * self.period


def sensor_columns(config: Config) -> tuple[str, ...]:
    """The robot's named sensors, logged every tick: the obstacle's force sensor, and six
    columns per force/torque sensor."""
    columns = ["contact_force_n"] if config.force_sensor.node_id else []
    for sensor in config.force_torque_sensors:
        columns += wrench_keys(sensor.name)
    return tuple(columns)


def run_experiment(
    config: Config,
    request: RunRequest,
    bus: JointBus,
    clock: LoopClock,
    meta: dict[str, Any],
    *,
    stop: StopFlag | None = None,
) -> RunResult:
    """Run one experiment on `bus` (built, not yet opened). See the module docstring."""
    own_stop = stop is None
    if stop is None:
        stop = StopFlag()
        stop.install()
    try:
        return Loop(config, request, bus, clock, meta, stop).run()
    finally:
        if own_stop:
            stop.restore()
