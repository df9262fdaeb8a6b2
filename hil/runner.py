"""One run of an experiment: the 200 Hz loop from bus to controller to bus, and every exit path.

A run, tick by tick (every tick reads the bus once, so in lock-step emulation tick k is the
plant at k periods):
    tick 0              read; start gate (no hardware error - with --reboot-first: reboot the
                        actuators that report one and read again -, both encoders valid, a
                        plausible deflection - wrong zero offsets show up here); torque on
                        (goal = present)
    ticks 0..S-1        hold the present position (S = [loop] stop_cycles)
    ticks S..S+H-1      only if the link starts away from the experiment's start: slow
                        re-homing (hil/recovery.py), H ticks, by the actuator's own position
                        servo (goal = the ramp); the controller and the experiment's time start
                        after it
    ticks S+H..end      controller + supervisor, along the experiment's reference
    last S ticks        hold the last goal, then the configured exit torque state
When the supervisor latches torque_off, the loop turns torque off at once; if the bus does not
take it (a silent device), it tries again every DISABLE_RETRY_TICKS ticks, not every tick (each
try costs the driver's timeouts), and on the tick the actuators answer again.
Every exit path - the end, Ctrl-C, SIGTERM, an exception in the controller or the bus - goes
through the same `finally`: the configured exit torque state is applied (best effort on every
joint, whatever the bus raises), the bus is closed, summary.json is written, and the log files
are closed. The log is line-buffered, so what was logged before a crash is on disk.
"""

from __future__ import annotations

import math
import signal
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import can
import numpy as np

from controller import (
    ControllerParams,
    FlexibleJointParams,
    LqrWeights,
    PendulumGravity,
    make_controller,
)
from controller.controllers import JointController
from drivers.joint_bus import BusError, HardwareError, JointBus, JointSample
from hil.clock import LoopClock
from hil.config import Config
from hil.experiments import Experiment
from hil.hardware import current_limit_a
from hil.metrics import contact_metrics, impact_metrics
from hil.recovery import HomingPlan, plan_homing
from hil.runlog import RunLog, read_log
from hil.supervisor import SafeState, SafetyEvent, Supervisor, WatchTuning

START_DEFLECTION_FACTOR = 1.0  # start gate: |deflection| must be below the safety bound
# The start gate reads again before refusing: the supervisor tolerates a lost reply or TPDO
# during a run, so one at the first read should not stop the run either. (Each extra read is a
# SYNC: in lock-step emulation the plant then starts that many periods ahead of tick 0; the
# widened lock-step timeouts make this practically never happen there.)
START_READ_ATTEMPTS = 3
DISABLE_RETRY_TICKS = 20  # a torque off the bus did not take is tried again this often
# What a bus raises when it is lost: the JointBus contract says BusError, but a port that
# vanishes (USB unplugged, emulator gone) surfaces as python-can's or pyserial's own errors
# (serial.SerialException is an OSError).
LOST_BUS_ERRORS = (BusError, can.CanError, OSError)


class StartRefused(RuntimeError):
    """The start gate found a reason not to turn torque on (nothing was moved)."""


@dataclass(frozen=True)
class RunRequest:
    experiment: Experiment
    controller: str
    kdist: float
    out_dir: Path
    duration_s: float | None = None
    overruns: tuple[tuple[float, float], ...] = ()  # injected loop overruns (start, duration)
    reboot_first: bool = False
    progress: bool = True

    @property
    def run_duration_s(self) -> float:
        return self.duration_s if self.duration_s is not None else self.experiment.duration_s


@dataclass
class RunResult:
    out_dir: Path
    termination: str
    metrics: dict[str, Any]
    safety_events: list[SafetyEvent] = field(default_factory=list)
    ticks: int = 0
    wall_time_s: float = 0.0

    @property
    def ok(self) -> bool:
        return self.termination == "completed"


def build_controller(config: Config, name: str, kdist: float, period_s: float) -> JointController:
    joints = config.joints
    params = ControllerParams(
        joints=FlexibleJointParams(
            stiffness_nm_per_rad=np.array([j.stiffness_nm_per_rad for j in joints]),
            damping_nms_per_rad=np.array([j.damping_nms_per_rad for j in joints]),
            servo_gain_per_s=np.array([j.servo_gain_per_s for j in joints]),
        ),
        lqr_weights=LqrWeights(
            tracking_error_weight=config.controller.q_error,
            state_increment_weight=config.controller.q_state,
            input_increment_weight=config.controller.r_input,
        ),
        kdist=kdist,
        dob_cutoff_hz=config.controller.dob_cutoff_hz,
        composition=config.controller.composition,  # type: ignore[arg-type]
        discretisation=config.controller.discretization,  # type: ignore[arg-type]
    )
    sm = np.diag([1.0 / j.link_inertia_kg_m2 for j in joints])
    # m*r is all the pendulum model needs: pass it as a mass at unit distance.
    gravity = PendulumGravity(
        np.array([j.gravity_moment_kg_m for j in joints]), np.ones(len(joints))
    )
    return make_controller(name, params, sm=sm, dt_s=period_s, gravity=gravity)


class StopFlag:
    """Set by SIGINT/SIGTERM; the loop checks it every tick and leaves through its `finally`.

    A session that runs several experiments installs one for all of them (`hil run` with no
    experiment stops the whole plan on Ctrl-C); `run_experiment` installs its own otherwise.
    """

    def __init__(self) -> None:
        self.reason: str | None = None
        self._previous: dict[int, Any] = {}

    def __call__(self, signum: int, _frame: object) -> None:
        self.reason = f"interrupted ({signal.Signals(signum).name})"

    def install(self) -> None:
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._previous[sig] = signal.signal(sig, self)

    def restore(self) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
        self._previous.clear()


def run_experiment(
    config: Config,
    request: RunRequest,
    bus: JointBus,
    clock: LoopClock,
    meta: dict[str, Any],
    *,
    on_progress: Callable[[float, float], None] | None = None,
    stop: StopFlag | None = None,
) -> RunResult:
    """Run one experiment on `bus` (already built, not yet opened). See the module docstring."""
    experiment = request.experiment
    period = clock.period_s
    n = len(config.joints)
    safety = config.safety
    tuning = WatchTuning(
        link_noise_jump_rad=safety.link_noise_jump_rad,
        link_noise_window_ticks=safety.link_noise_window_ticks,
        link_noise_fraction=safety.link_noise_fraction,
        overrun_window_s=safety.overrun_window_s,
        on_link_noisy=safety.on_link_noisy,
        on_command_invalid=safety.on_command_invalid,
    )
    supervisor = Supervisor(
        safety, config.joints, period, np.array(current_limit_a(config)), tuning=tuning
    )
    supervisor.check_reference(experiment.min_reference_rad, experiment.max_reference_rad)
    controller = build_controller(config, request.controller, request.kdist, period)
    total_ticks = int(round(request.run_duration_s / period))
    hold_ticks = config.loop.stop_cycles
    homing: HomingPlan | None = None
    homing_ticks = 0
    log = RunLog(request.out_dir, config.joint_names, meta)
    own_stop = stop is None
    if stop is None:
        stop = StopFlag()
        stop.install()
    termination = "completed"
    opened = False
    torque_on = False
    tick_index = 0
    started = time.perf_counter()
    last_goal = np.full(n, math.nan)
    hold_goal = np.full(n, math.nan)
    last_link = np.full(n, math.nan)
    controller_started = False
    zeros = np.zeros(n)
    no_goal = np.full(n, math.nan)  # logged on ticks that send nothing (read-only, never written)
    disable_retry_tick = 0
    disable_failures = 0
    last_step_tick = -1
    current_limits = np.full(n, math.nan)
    answered_before = True
    logged_events = logged_notices = 0
    try:
        bus.open()
        opened = True
        log.event(0.0, "open", f"bus open: {', '.join(config.joint_names)}")
        while tick_index < total_ticks + hold_ticks:
            if stop.reason is not None:
                termination = stop.reason
                break
            tick = clock.next_tick()
            # The clock's grid index: after a missed deadline the wall clock skips ticks, and
            # the reference, the faults and the log follow the grid, not the loop's count.
            k = tick.index
            time_s = tick.time_s
            if k >= total_ticks + hold_ticks:
                break
            t_read = time.perf_counter()
            sample = bus.read()
            t_compute = time.perf_counter()
            if k == 0:
                sample = _start_gate(config, sample, supervisor, request, bus, log)
                current_limits = _current_limits(config, bus)
                supervisor.set_current_limits(current_limits)
                if config.safety.current_guard and not np.isfinite(current_limits).all():
                    log.event(
                        time_s,
                        "current_guard_inactive",
                        "the software overload guard cannot act: an actuator's current limit "
                        "is unknown (set torque_limit_a in the configuration)",
                    )
                bus.enable()
                torque_on = True
                hold_goal = sample.motor_angle_rad.copy()
                last_goal = hold_goal.copy()
                log.event(time_s, "torque_on", "torque on; holding the present position")
                homing = plan_homing(sample.link_angle_rad, experiment.reference(0.0))
                if homing is not None:
                    homing_ticks = homing.ticks(period)
                    total_ticks += homing_ticks
                    log.event(time_s, "homing", homing.describe())
            overrun = _injected_overrun(request.overruns, time_s, period, clock)
            if tick.skipped or overrun:
                supervisor.note_overrun(k, time_s, tick.skipped)
            for note in sample.notes:
                log.event(time_s, "bus_note", note, tick=k)
            supervisor.observe(k, time_s, sample)
            logged_events, logged_notices = _log_safety(
                supervisor, log, request, logged_events, logged_notices
            )
            if k == 0:
                # this tick's sample predates the enable: expect torque from the next one on
                supervisor.torque_enabled(hold_goal)
            answered = bool(sample.motor_valid.all())
            if (
                supervisor.state == SafeState.TORQUE_OFF
                and torque_on
                and (k >= disable_retry_tick or (answered and not answered_before))
            ):
                why = "safety stop" + (f" (try {disable_failures + 1})" if disable_failures else "")
                torque_on = not _disable(bus, log, time_s, why, quiet=disable_failures > 0)
                supervisor.torque_disabled()
                if torque_on:
                    disable_failures += 1
                    disable_retry_tick = k + DISABLE_RETRY_TICKS
            answered_before = answered
            if homing is not None and k < hold_ticks + homing_ticks:
                reference = homing.reference((k - hold_ticks) * period)
            else:
                reference = np.full(n, experiment.reference(time_s - homing_ticks * period))
            link = np.where(sample.link_valid, sample.link_angle_rad, last_link)
            last_link = link
            proposed = None
            in_experiment = hold_ticks + homing_ticks <= k < total_ticks
            if k >= total_ticks:
                proposed = last_goal  # stop cycles: hold the last goal
            elif k < hold_ticks:
                proposed = hold_goal
            elif not in_experiment:
                proposed = reference  # re-homing: the actuator's own servo follows the ramp
            elif not supervisor.safe and sample.motor_valid.all() and np.isfinite(link).all():
                if not controller_started:
                    controller.reset(sample.motor_angle_rad, link, reference)
                    controller_started = True
                elif k - last_step_tick > 1:  # ticks without a step: do not read them as motion
                    controller.resync(sample.motor_angle_rad, link)
                proposed = controller.step(sample.motor_angle_rad, link, reference)
                last_step_tick = k
            goal = supervisor.command(proposed, sample) if torque_on else None
            if proposed is not None and in_experiment and controller_started:
                controller.notify_applied(goal if goal is not None else proposed)
            if goal is not None:
                bus.write(goal)
                last_goal = goal
            logged_events, logged_notices = _log_safety(
                supervisor, log, request, logged_events, logged_notices
            )
            t_done = time.perf_counter()
            terms = controller.terms if controller_started else None
            log.write_row(
                {
                    "tick": k,
                    "time_s": time_s,
                    "contact_force_n": sample.extra.get("contact_force_n", math.nan),
                    "supervisor_state": supervisor.state.name.lower(),
                    "skipped_ticks": tick.skipped,
                    "slack_s": tick.slack_s,
                    "measured_period_s": tick.measured_period_s,
                },
                {
                    "reference_rad": reference,
                    "goal_rad": goal if goal is not None else no_goal,
                    "motor_angle_rad": sample.motor_angle_rad,
                    "link_angle_rad": sample.link_angle_rad,
                    "deflection_rad": sample.link_angle_rad - sample.motor_angle_rad,
                    "motor_velocity_rad_s": sample.motor_velocity_rad_s,
                    "motor_current_a": sample.motor_current_a,
                    "hardware_error": sample.hardware_error,
                    "torque_enabled": sample.torque_enabled,
                    "motor_valid": sample.motor_valid,
                    "link_valid": sample.link_valid,
                    "link_age_s": sample.link_age_s,
                    "uc_rad": terms.uc if terms else zeros,
                    "d_hat_rad": terms.d_hat if terms else zeros,
                    "ug_rad": terms.ug if terms else zeros,
                },
            )
            log.write_timing(k, t_compute - t_read, t_done - t_compute, 0.0)
            tick_index = k + 1
            if on_progress is not None and k % int(round(1.0 / period)) == 0:
                on_progress(time_s, request.run_duration_s)
        if termination == "completed" and supervisor.first_trip is not None:
            first = supervisor.first_trip
            termination = f"safety stop: {first.cause} ({first.action})"
    except StartRefused as exc:
        termination = f"start refused: {exc}"
        log.event(0.0, "start_refused", str(exc))
    except LOST_BUS_ERRORS as exc:
        termination = f"bus failure: {exc}"
        log.event(tick_index * period, "bus_failure", f"{type(exc).__name__}: {exc}")
    except Exception as exc:
        termination = f"error: {type(exc).__name__}: {exc}"
        log.event(tick_index * period, "error", termination)
        raise
    finally:
        _log_safety(supervisor, log, request, logged_events, logged_notices)
        exit_notes = _exit_path(config, bus, log, opened, torque_on, tick_index * period)
        if own_stop:
            stop.restore()
        metrics = _metrics_or_error(request, log, homing_ticks * period)
        summary = {
            "experiment": experiment.name,
            "controller": request.controller,
            "kdist": request.kdist if request.controller == "gc+lqr+dob" else None,
            "termination": termination,
            "ticks": tick_index,
            "wall_time_s": time.perf_counter() - started,
            "exit": exit_notes,
            "safety_events": [vars(e) for e in supervisor.events],
            "safety_notices": [vars(e) for e in supervisor.notices],
            "safety_counters": supervisor.counters(),
            "homing": homing.to_dict() if homing is not None else None,
            "current_limit_a": current_limits.tolist(),
            "metrics": metrics,
        }
        log.write_summary(summary)
        log.close()
    return RunResult(
        request.out_dir,
        termination,
        metrics,
        supervisor.events,
        tick_index,
        time.perf_counter() - started,
    )


def _current_limits(config: Config, bus: JointBus) -> np.ndarray:
    """What the actuators report (read at open), else what the configuration sets."""
    reported = np.asarray(bus.current_limits_a(), dtype=float)
    configured = np.array(current_limit_a(config))
    return np.where(np.isfinite(reported), reported, configured)


def _start_gate(
    config: Config,
    sample: JointSample,
    supervisor: Supervisor,
    request: RunRequest,
    bus: JointBus,
    log: RunLog,
) -> JointSample:
    """Refuse to start (StartRefused, nothing moved) or return the sample to start from.

    With --reboot-first, actuators that report a hardware error are rebooted and the bus is
    read again (the one extra read of a run: the devices' state changed).
    """
    for attempt in range(1, START_READ_ATTEMPTS):
        if sample.motor_valid.all() and sample.link_valid.all():
            break
        log.event(
            0.0,
            "start_retry",
            f"first read incomplete ({'; '.join(sample.bus_errors)}): reading again ({attempt})",
        )
        sample = bus.read()
    to_reboot = []
    for i, joint in enumerate(config.joints):
        if not sample.motor_valid[i]:
            raise StartRefused(
                f"actuator {joint.dynamixel_id} ({joint.name}) did not answer the first read: "
                + "; ".join(sample.bus_errors)
            )
        bits = int(sample.hardware_error[i])
        if bits:
            if not request.reboot_first:
                raise StartRefused(
                    f"actuator {joint.dynamixel_id} ({joint.name}) reports "
                    f"{HardwareError.describe(bits)} (0x{bits:02X}); remove the cause, then run "
                    "`hil reboot` or pass --reboot-first"
                )
            log.event(
                0.0,
                "reboot",
                f"rebooting actuator {joint.dynamixel_id} ({joint.name}): it reports "
                f"{HardwareError.describe(bits)} (0x{bits:02X})",
                joint=joint.name,
            )
            to_reboot.append(i)
    if to_reboot:
        statuses = bus.reboot(to_reboot)
        log.event(
            0.0,
            "reboot",
            "after reboot, Hardware Error Status: "
            + ", ".join(f"ID {i} {HardwareError.describe(b)}" for i, b in statuses.items()),
        )
        sample = bus.read()
        for i, joint in enumerate(config.joints):
            if not sample.motor_valid[i] or int(sample.hardware_error[i]):
                raise StartRefused(
                    f"actuator {joint.dynamixel_id} ({joint.name}) still reports "
                    f"{HardwareError.describe(int(sample.hardware_error[i]))} after a reboot "
                    f"(or did not answer: {'; '.join(sample.bus_errors) or 'ok'}): the cause "
                    "persists (load, temperature, supply voltage?)"
                )
    for i, joint in enumerate(config.joints):
        if not sample.link_valid[i]:
            raise StartRefused(
                f"link encoder node {joint.encoder_node_id} ({joint.name}) did not answer the "
                "first SYNC"
            )
        motor = float(sample.motor_angle_rad[i])
        if not joint.min_angle_rad <= motor <= joint.max_angle_rad:
            raise StartRefused(
                f"joint {joint.name}: the motor stands at {motor:+.4f} rad, outside the joint's "
                f"range [{joint.min_angle_rad:+.3f}, {joint.max_angle_rad:+.3f}] rad: move it "
                "inside by hand (torque is off), or widen the range in the configuration"
            )
        deflection = float(sample.link_angle_rad[i] - sample.motor_angle_rad[i])
        bound = START_DEFLECTION_FACTOR * config.safety.max_deflection_rad
        if abs(deflection) > bound:
            raise StartRefused(
                f"joint {joint.name}: link minus motor angle is {deflection:+.4f} rad at rest "
                f"(more than {bound} rad): are encoder_offset_rad and motor_offset_rad set?"
            )
    return sample


def _injected_overrun(
    overruns: tuple[tuple[float, float], ...], time_s: float, period: float, clock: LoopClock
) -> bool:
    for start, duration in overruns:
        if start <= time_s < start + max(duration, period):
            if not clock.deterministic:
                time.sleep(period * 1.5)  # really miss the deadline
            return True
    return False


def _disable(bus: JointBus, log: RunLog, time_s: float, why: str, quiet: bool = False) -> bool:
    """Torque off on every joint; False (and logged, unless `quiet`) if the bus did not take it.

    Any exception counts as a failure: on an exit path a lost port may raise what it likes,
    and the log must still be completed.
    """
    try:
        bus.disable()
    except Exception as exc:  # noqa: BLE001 - best effort, reported
        if not quiet:
            log.event(time_s, "torque_off_failed", f"{why}: could not turn torque off: {exc}")
        return False
    log.event(time_s, "torque_off", f"{why}: torque off")
    return True


def _log_safety(
    supervisor: Supervisor, log: RunLog, request: RunRequest, events_done: int, notices_done: int
) -> tuple[int, int]:
    """Write the supervisor's new events and notices to events.jsonl; returns the new counts."""
    for event in supervisor.events[events_done:]:
        log.event(
            event.time_s,
            event.cause,
            event.message,
            joint=event.joint,
            action=event.action,
            state=event.state,
            tick=event.tick,
        )
        _print_event(request, event)
    for notice in supervisor.notices[notices_done:]:
        log.event(notice.time_s, notice.kind, notice.message, joint=notice.joint, tick=notice.tick)
    return len(supervisor.events), len(supervisor.notices)


def _exit_path(
    config: Config, bus: JointBus, log: RunLog, opened: bool, torque_on: bool, time_s: float
) -> list[str]:
    notes: list[str] = []
    if opened:
        if config.safety.on_exit == "torque_off":
            if _disable(bus, log, time_s, "exit"):
                notes.append("torque off")
            else:
                notes.append("torque off FAILED (see events.jsonl)")
        else:
            notes.append(f"torque left {'on' if torque_on else 'off'} (on_exit = hold)")
            log.event(time_s, "exit_hold", "exit: torque left as it was (on_exit = hold)")
        try:
            bus.close()
        except Exception as exc:  # noqa: BLE001 - best effort, reported
            notes.append(f"close failed: {exc}")
            log.event(time_s, "close_failed", str(exc))
    else:
        notes.append("bus never opened: nothing was sent")
    return notes


def _metrics_or_error(request: RunRequest, log: RunLog, homing_s: float = 0.0) -> dict[str, Any]:
    if log.rows < 2:
        return {}
    try:
        columns = read_log(log.dir / "log.csv")
        experiment = request.experiment
        joint = "" if len(log.joint_names) == 1 else log.joint_names[0]
        if experiment.name == "contact":
            return contact_metrics(columns, joint)
        if experiment.name == "impact" and experiment.pushes:
            return impact_metrics(columns, experiment.pushes[0].start_s + homing_s, joint)
    except (ValueError, KeyError) as exc:
        return {"error": str(exc)}
    return {}


def _print_event(request: RunRequest, event: SafetyEvent) -> None:
    if request.progress:
        print(
            f"  [{event.time_s:7.3f} s] {event.cause} -> {event.action}: {event.message}",
            file=sys.stderr,
        )
