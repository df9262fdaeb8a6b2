"""One run of an experiment: the 200 Hz loop from bus to controller to bus, and every exit path.

Each cycle is the spine's (hil/loop/spine.py): `begin_cycle` (read, watch), the phase's
proposal, `cycle_actuation` (through the supervisor to the bus), `end_cycle` (the record). What
the phase proposes (hil/loop/timeline.py):
    tick 0      read; the start gate (hil/loop/start_gate.py); torque on (goal = present);
                plan the re-homing if the link starts away from the experiment's start
    HOLD        hold the present position
    HOMING      the slow ramp, followed by the actuator's own position servo
    EXPERIMENT  the controller along the experiment's reference (it starts bumplessly from the
                goal in force; it is not stepped while the supervisor holds a safe state - it is
                during a `finish_step`, until the experiment's rest; an
                experiment with a `ReferenceFeedback` corrects the reference from the tick's
                measured link angles first, and the log records the corrected one), or,
                for an open-loop experiment (identification), the goal in force at its start
                plus the experiment's own goal offsets, with no controller
    STOP        hold the last goal; then the configured exit torque state
The controller is any registry entry (hil/controllers/): it is stepped through its contract,
and one that raises or returns what is not a goal is stopped by the supervisor
(`controller_fault`: torque off by default), its traceback in events.jsonl.

Every exit path - the end, Ctrl-C, SIGTERM, an exception in the controller or the bus - goes
through the same `finally`: the configured exit torque state is applied (best effort on every
joint, whatever the bus raises), the bus is closed, summary.json is written, and the log files
are closed. The log is written by a process of its own (hil/output/log_process.py), which has
every tick's rows at the end of that tick and writes what it has when this process ends, however
it ends; a writer that ends or stalls before the run stops the run like a lost bus, and the
loop writes the record's rest itself (after the exit path: `_finish`, the exit notes and
summary.json's `record` say so); one lost only at the end leaves a completed run. A record that
could not be written whole (a full disk) makes a run that ran its course a bus failure. With the
live view the log stays in this process, a line at a time, a tick's rows written during the next
tick (hil/loop/run_record.py).
"""

from __future__ import annotations

import contextlib
import dataclasses
import gc
import time
import traceback
from typing import Any

import numpy as np

from controller import PlannedMotion
from drivers.joint_bus import JointBus, JointDevices, JointSample, wrench_keys
from hil.config import Config
from hil.controllers import ControlInput, Controller, build
from hil.controllers.paper import PaperController
from hil.controllers.paper_factory import joint_params
from hil.controllers.preflight import goal_problem, terms_problem
from hil.controllers.robot_model import RobotModel, robot_model
from hil.controllers.setup import controller_setup
from hil.experiments import Experiment
from hil.loop.clock import LoopClock, Tick
from hil.loop.experiment_feed import ExperimentFeed
from hil.loop.gain_scheduler import GainScheduler
from hil.loop.request import RunRequest, StopFlag
from hil.loop.run_record import RunRecord
from hil.loop.spine import LOST_BUS_ERRORS, Spine
from hil.loop.timeline import Phase
from hil.output.log_process import LogWriterLost, open_run_log
from hil.output.record_files import RecordWriteError
from hil.output.records import RunResult
from hil.output.rundir import load_run
from hil.output.runlog import RECORD_INCOMPLETE
from hil.safety import Supervisor, protections_of
from hil.vocabulary import RunEnding, SafetyCause, Termination
from hil.wiring.process_activity import ProcessActivity, proc_available

__all__ = ["LOST_BUS_ERRORS", "Loop", "run_experiment", "sensor_columns", "supervisor_for"]


def supervisor_for(
    config: Config, devices: tuple[JointDevices, ...], period_s: float
) -> Supervisor:
    """The safety supervisor of the configured joints (limits, stiffness, `[safety]`)."""
    return Supervisor(
        config.safety,
        config.joint_names,
        devices,
        np.array([j.min_angle_rad for j in config.joints]),
        np.array([j.max_angle_rad for j in config.joints]),
        period_s,
        joint_params(config).stiffness_nm_per_rad,
        protections_of(config),
    )


class Loop:
    """One run of an experiment with a controller; `run()` returns its result. See the module
    docstring. Composed of: the spine (bus, supervisor, torque, record), the experiment's feed
    (timeline, reference, open-loop goals, LQR contacts), the controller, and on the humanoid
    the LQR's gain scheduler."""

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
        self.clock = clock
        self.stop = stop
        self.period = clock.period_s
        self.n = n = len(config.joints)
        supervisor = supervisor_for(config, bus.devices(), self.period)
        low, high = self.experiment.reference_range(n)
        supervisor.check_reference(low, high)
        supervisor.set_reaction_policy(self.experiment.reaction_policy())
        self.robot: RobotModel = robot_model(config)
        self.feed = ExperimentFeed(
            config, self.experiment, request.choice, self.robot, self.period, request.run_duration_s
        )
        self.controller: Controller = self._build_controller()
        self.scheduler = self._gain_scheduler()
        columns = sensor_columns(config)
        terms = self.controller.term_names
        log = open_run_log(
            request.out_dir,
            config.joint_names,
            meta,
            columns,
            mcap=request.mcap,
            sinks=request.sinks,
            term_columns=terms,
            activity=writer_activity,
        )
        self.spine = Spine(
            config,
            bus,
            clock,
            supervisor,
            log,
            RunRecord(log, columns, terms, n),
            reboot_first=request.reboot_first,
            say=request.on_event,
            on_torque_on=self._on_torque_on,
            check_settings=self._check_settings if request.choice.uses_kdist else None,
            overruns=request.overruns,
        )
        self.supervisor = supervisor
        self.log = log
        # the experiment's phase state the controller sees, and where it stepped last
        self._support: object = None
        self._planned_motion: PlannedMotion | None = None
        self._kdist: np.ndarray | None = None
        self._controller_started = False
        self._terms_checked = False  # the controller's terms() against its term_names, once
        self._last_step_tick = -1
        self._last_link = np.full(n, np.nan)

    def _build_controller(self) -> Controller:
        """The chosen controller for this robot, at the experiment's start posture."""
        setup = controller_setup(
            self.config,
            self.period,
            self.robot,
            self.feed.start_reference,
            self.feed.lqr_contacts[0],
        )
        return build(self.request.choice, setup, self.config.controller.params)

    def _gain_scheduler(self) -> GainScheduler | None:
        """The paper's LQR rescheduled with posture and contact, on a robot whose Sm changes."""
        kind = self.request.choice.kind
        controller = self.controller
        if not (self.robot.rescheduled and kind is not None and kind.has_lqr):
            return None
        assert isinstance(controller, PaperController)
        return GainScheduler(
            self.robot,
            controller.joint_controller,
            self.period,
            self.config.model.gain_reschedule_period_s,
            wall_clock=not self.clock.deterministic,
            stop=self.stop,
        )

    # --- the run -------------------------------------------------------------------------------
    def run(self) -> RunResult:
        started = time.perf_counter()
        try:
            self.spine.run(self._cycles)
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
        state = self.spine.state
        while state.ticks_done < self.feed.timeline.end:
            if self.stop.reason is not None:
                state.ending = RunEnding(Termination.INTERRUPTED, self.stop.reason)
                return
            tick = self.clock.next_tick()
            # The clock's grid index: after a missed deadline the wall clock skips ticks, and the
            # reference, the faults and the log follow the grid, not the loop's count.
            if tick.index >= self.feed.timeline.end:
                break
            self._cycle(tick)
        first = self.supervisor.first_trip
        if first is not None:
            state.ending = RunEnding(Termination.SAFETY_STOP, f"{first.cause} ({first.action})")

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
        k, spine, feed = tick.index, self.spine, self.feed
        sample = spine.begin_cycle(tick)
        proposed, reference = self._propose(k, sample, feed.reference_row(k))
        phase = feed.timeline.phase(k)
        goal = spine.cycle_actuation(proposed)
        stepped = proposed is not None and phase is Phase.EXPERIMENT and self._controller_started
        if stepped and feed.open_loop is None:
            self.controller.applied(goal if goal is not None else proposed)
        terms = self.controller.terms() if self._controller_started else None
        spine.end_cycle(reference, phase, terms)
        feed.fill_ahead(k)
        on_progress = self.request.on_progress
        if on_progress is not None and k % int(round(1.0 / self.period)) == 0:
            on_progress(tick.time_s, feed.timeline.end * self.period)

    # --- tick 0 (the spine's hooks) ------------------------------------------------------------
    def _on_torque_on(self, sample: JointSample) -> None:
        homing = self.feed.plan_start(sample.link_angle_rad)
        if homing is not None:
            self.log.event(0.0, "homing", homing.describe())
        if self.feed.feedback is not None:
            self.log.event(0.0, "reference_feedback", self.feed.feedback.describe())

    def _check_settings(self, supervisor: Supervisor) -> None:
        supervisor.check_settings(self.request.choice.kdist)

    # --- each tick ---------------------------------------------------------------------------
    def _propose(
        self, k: int, sample: JointSample, reference: np.ndarray
    ) -> tuple[np.ndarray | None, np.ndarray]:
        """The goal this phase proposes (None: the controller cannot step this tick), and the
        reference it followed (the table's, or as the experiment's feedback corrected it)."""
        link = np.where(sample.link_valid, sample.link_angle_rad, self._last_link)
        self._last_link = link
        state = self.spine.state
        phase = self.feed.timeline.phase(k)
        if phase is Phase.STOP:
            return state.last_goal, reference
        if phase is Phase.HOLD:
            return state.hold_goal, reference
        if phase is Phase.HOMING:
            return reference, reference  # the actuator's own servo follows the ramp
        n = self.n
        if (
            not self.supervisor.controller_steps
            or np.count_nonzero(sample.motor_valid) != n
            or np.count_nonzero(np.isfinite(link)) != n
        ):
            return None, reference
        assert state.last_goal is not None
        if self.feed.open_loop is not None:
            return self.feed.open_loop_goal(k, state.last_goal), reference
        self._schedule(k, link)
        feedback = self.feed.feedback
        if feedback is not None:
            time_s = self.feed.timeline.experiment_time_s(k)
            reference = feedback.reference(time_s, reference, link, sample.motor_angle_rad)
        return self._step(k, sample, link, reference, state.last_goal), reference

    def _schedule(self, k: int, link: np.ndarray) -> None:
        """What the experiment's phase sets: the support state (gravity compensator), the LQR's
        contact (Sm and the gain), a walk's planned motion and a Kdist schedule (the controller
        ramps between values)."""
        feed = self.feed
        time_s = feed.timeline.experiment_time_s(k)
        support = self.experiment.support(time_s)
        if support != self._support:
            self.robot.set_support(support)
            self._support = support
        if self.scheduler is not None:
            lead = self.scheduler.lead_ticks
            self.scheduler.update(k, link, feed.lqr_contact(k), feed.lqr_contact(k + lead))
        motion = self.experiment.planned_motion(time_s)  # a walk's plan: GC load, LQR
        self.robot.set_planned_motion(motion)
        self._planned_motion = motion
        choice = self.request.choice
        if choice.uses_kdist:
            kdist = self.experiment.kdist_at(time_s, choice.kdist)
            if kdist is not None and (self._kdist is None or np.any(kdist != self._kdist)):
                self.controller.set_kdist(kdist)
                self._kdist = np.array(kdist, dtype=float)

    def _step(
        self,
        k: int,
        sample: JointSample,
        link: np.ndarray,
        reference: np.ndarray,
        goal_in_force: np.ndarray,
    ) -> np.ndarray | None:
        """The controller's goal through its contract (None: it broke it, the supervisor
        stops the run)."""
        state = ControlInput(
            tick=k,
            time_s=self.feed.timeline.experiment_time_s(k),
            motor_angle_rad=sample.motor_angle_rad,
            link_angle_rad=link,
            motor_velocity_rad_s=sample.motor_velocity_rad_s,
            motor_current_a=sample.motor_current_a,
            reference_rad=reference,
            goal_in_force_rad=goal_in_force,
            ticks_since_step=k - self._last_step_tick if self._controller_started else 0,
            support=self._support,
            planned_motion=self._planned_motion,
        )
        controller = self.controller
        try:
            if not self._controller_started:  # bumpless: from the goal the servo is driven with
                controller.start(state)
                self._controller_started = True
            self._last_step_tick = k
            goal = controller.step(state)
        except Exception as exc:  # noqa: BLE001 - the controller's fault: torque off, recorded
            self._controller_fault(state.time_s, "raised", exc)
            return None
        problem = goal_problem(goal, self.n)
        if problem is None and not self._terms_checked:
            problem = terms_problem(controller, self.n)
            self._terms_checked = True
        if problem is not None:
            self._controller_fault(state.time_s, problem)
            return None
        return goal

    def _controller_fault(self, time_s: float, what: str, exc: Exception | None = None) -> None:
        """The controller broke its contract: the supervisor's CONTROLLER_FAULT (torque off by
        default), the traceback in events.jsonl."""
        if exc is not None:
            what = f"{what} {type(exc).__name__}: {exc}"
            trace = "".join(traceback.format_exception(exc))
            self.log.event(time_s, "controller_traceback", trace, tick=self.spine.state.ticks_done)
        self.supervisor.trip(
            SafetyCause.CONTROLLER_FAULT, None, f"controller {self.request.choice.name}: {what}"
        )
        self.spine.news.log_new()

    # --- every exit path -----------------------------------------------------------------------
    def _finish(self, wall_time_s: float) -> None:
        spine, state = self.spine, self.spine.state
        # A writer lost at the end: the run's last rows are kept, and written by the loop with
        # the rest (hil/output/log_process.py); only a record that cannot be written whole
        # makes a run that ran its course a failure (below).
        with contextlib.suppress(LogWriterLost):
            spine.record.write_kept()
        if self.scheduler is not None:
            self.scheduler.close()
        exit_notes = spine.close()
        metrics = self._metrics()
        record_note = self.log.record_note()  # (the log is closed: the record is on disk)
        if record_note is not None:
            exit_notes.append(record_note)
            if self.request.on_event is not None:
                self.request.on_event(f"  {record_note}")
            if state.ending.ok and record_note.startswith(RECORD_INCOMPLETE):
                state.ending = RunEnding(Termination.BUS_FAILURE, record_note)
        choice = self.request.choice
        feed = self.feed
        summary = {
            "experiment": self.experiment.name,
            "controller": choice.name,
            "controller_label": choice.label,
            "kdist": choice.kdist if choice.uses_kdist else None,
            "termination": state.ending.text,
            "ticks": state.ticks_done,
            "wall_time_s": wall_time_s,
            "exit": exit_notes,
            **spine.safety_summary(),
            "homing": feed.homing.to_dict() if feed.homing is not None else None,
            "experiment_start_s": feed.timeline.experiment_start_s,
            "current_limit_a": spine.current_limits,
            "gain_schedule": self.scheduler.schedule.record() if self.scheduler else None,
            "reference_feedback": feed.feedback.describe() if feed.feedback else None,
            "metrics": metrics,
        }
        try:
            self.log.write_summary(summary)
        except RecordWriteError as exc:  # the result and the --json line still say it all
            exit_notes.append(f"summary.json not written: {exc}")
        self.log.close()
        self.result = RunResult(
            self.request.out_dir,
            state.ending,
            metrics,
            list(self.supervisor.events),
            state.ticks_done,
            wall_time_s,
            tuple(exit_notes),
            spine.torque.exit_failed,
        )

    def _metrics(self) -> dict[str, Any]:
        if self.log.rows < 2:
            return {}
        self.log.close()  # flushed and complete before it is read back
        try:
            run = load_run(self.log.dir)  # summary.json comes after the metrics: say when the
            # experiment's timeline started here
            summary = {"experiment_start_s": self.feed.timeline.experiment_start_s}
            return self.experiment.metrics(dataclasses.replace(run, summary=summary))
        except (ValueError, KeyError) as exc:
            return {"error": str(exc)}


def writer_activity(pid: int) -> ProcessActivity | None:
    """How the log writer's process is looked at (hil/output/writer_watch.py)."""
    return ProcessActivity(pid) if proc_available() else None


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
