"""The Python API: open the robot a configuration describes and run a 200 Hz loop from your own
code, with the safety supervisor in front of the bus and the run's record kept, as `hil run`
does (it is built from the same parts: hil/loop/spine.py).

    open_robot(...)   the robot: on its hardware, against an attached `hil emulate`, on an
                      embedded emulator (the default), or in process (`Setup`)
    Robot.run(...)    one experiment with a controller, exactly as `hil run EXPERIMENT` does
    Robot.loop(...)   your own loop: `begin_cycle()` reads the bus (SI units, `JointSample`),
                      `cycle_actuation(goal)` sends a goal through the supervisor,
                      `end_cycle()` records the tick; lock-step when emulated, on the wall
                      clock on hardware; torque off and the record complete on every exit path
                      (an exception, Ctrl-C or SIGTERM, a lost bus)

A run writes the same directory as `hil run` (log.csv, events.jsonl, summary.json, meta.json,
timing.csv, run.mcap) and ends with a `RunResult` whose `exit_status` is `hil run`'s (0
completed, 1 a safety stop / failure / interrupt, 3 torque could not be turned off).

Example, a sine on the testbed's link through the supervisor (examples/sine_loop.py)::

    import math
    import hil

    with hil.open_robot(robot="testbed") as robot, robot.loop("sine", duration_s=2.0) as loop:
        for sample in loop:
            goal = sample.motor_angle_rad * 0 + 0.2 * math.sin(2 * math.pi * loop.time_s)
            sent = loop.cycle_actuation(goal)
    print(loop.result.ending, loop.result.out_dir)
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Iterator, Mapping
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np

from drivers.joint_bus import JointSample
from hil.config import Config, ConfigError, load_config
from hil.controllers import ControllerLoadError
from hil.controllers.choice import choose
from hil.experiments import Experiment
from hil.loop import LoopClock, StopFlag
from hil.loop.clock import Tick
from hil.loop.run_record import RunRecord
from hil.loop.runner import sensor_columns, supervisor_for
from hil.loop.spine import Spine, SpineState
from hil.loop.timeline import Phase
from hil.output.log_process import LogWriterLost, open_run_log
from hil.output.records import RunResult
from hil.output.rundir import create_run_dir, timestamp
from hil.robots import get_experiment
from hil.session.session import ConnectionOverrides, Session, Setup
from hil.vocabulary import ControllerChoice, RunEnding, Termination

__all__ = ["Robot", "RobotLoop", "RunStopped", "Setup", "open_robot"]


class RunStopped(Exception):
    """`begin_cycle()` after Ctrl-C or SIGTERM, or past the loop's duration: leave the loop
    (the `with` block ends the run; it does not re-raise this)."""


def open_robot(
    config: str | Path | Config | None = None,
    *,
    robot: str | None = None,
    setup: Setup | str = Setup.EMBEDDED,
    attach: Mapping[str, Any] | None = None,
    realtime: bool = False,
    seed: int | None = None,
    out_root: str | Path = "runs",
    quiet: bool = True,
) -> Robot:
    """The robot a configuration describes (a path, a `Config`, or None for the built-in one of
    `robot`, a name of hil.vocabulary.Robot: "testbed", the default, or "dyros-jet"), where
    `setup` says:

    Setup.EMBEDDED    a fresh emulator per run, lock-step (deterministic), or on the wall clock
                      with `realtime` (the default: no hardware needed)
    Setup.IN_PROCESS  the emulated robot in this process, no buses (fast, for tests)
    Setup.ATTACHED    a running `hil emulate`: `attach` is the JSON line it printed (a dict)
    Setup.HARDWARE    the ports the configuration names: the real robot, on the wall clock

    Bad input raises `hil.config.ConfigError` before anything opens.

    >>> import hil
    >>> robot = hil.open_robot(robot="testbed")
    >>> robot.description
    'emulated testbed, lock-step; GC compliance: joint'
    """
    if isinstance(config, Config):
        loaded = config
    else:
        loaded = load_config(config) if robot is None else load_config(config, robot=robot)
    where = Setup(setup)
    if (where is Setup.ATTACHED) != (attach is not None):
        raise ConfigError("attach= goes with setup=Setup.ATTACHED (the JSON `hil emulate` printed)")
    session = Session(
        loaded,
        where,
        realtime=realtime,
        attach=dict(attach) if attach is not None else None,
        overrides=ConnectionOverrides(),
        seed=seed,
        out_root=Path(out_root),
        plots=False,
        quiet=quiet,
    )
    return Robot(session)


class Robot:
    """A configured robot and where it is (`open_robot`). Use it as a context manager or not:
    it holds nothing open itself; each run opens and closes its own bus (and emulator)."""

    def __init__(self, session: Session) -> None:
        self.session = session

    @property
    def config(self) -> Config:
        return self.session.config

    @property
    def description(self) -> str:
        return self.session.description

    def __enter__(self) -> Robot:
        return self

    def __exit__(self, *exc_info: object) -> None:
        return None

    def run(
        self,
        experiment: str | Experiment,
        controller: str | None = None,
        *,
        duration_s: float | None = None,
        plots: bool = False,
    ) -> RunResult:
        """One experiment with a controller (a registry name, "path/to/file.py:Class" or
        "package.module:Class"; default the configuration's `[controller] name`), its parameters
        from `[controller.params]`: what `hil run EXPERIMENT --controller ...` does.

        >>> import hil
        >>> robot = hil.open_robot(robot="testbed", out_root="/tmp/hil-doctest")
        >>> result = robot.run("impact", "pid", duration_s=1.0)
        >>> result.ending.text, result.exit_status
        ('completed', 0)
        """
        chosen = experiment if isinstance(experiment, Experiment) else _experiment(experiment)
        choice = self._choice(controller, chosen)
        self.session.plots = plots
        return self.session.run_one(chosen, choice, duration_s=duration_s, print_result=False)

    def _choice(self, controller: str | None, experiment: Experiment) -> ControllerChoice:
        config = self.config
        spec = controller or config.controller.name
        try:
            choice = choose(spec, config, experiment)
        except ControllerLoadError as exc:
            raise ConfigError(f"controller {spec!r}: {exc}") from None
        if choice.uses_kdist and choice.kdist > config.safety.max_kdist:
            raise ConfigError(
                f"[controller] kdist = {choice.kdist:g} is above [safety] max_kdist = "
                f"{config.safety.max_kdist:g}"
            )
        return choice

    def loop(
        self,
        name: str = "loop",
        *,
        duration_s: float | None = None,
        experiment: str | Experiment | None = None,
        out_dir: str | Path | None = None,
    ) -> RobotLoop:
        """Your own loop on this robot (see `RobotLoop`): `duration_s` bounds the iteration
        (None: until you leave it or Ctrl-C); `experiment` names the world an embedded emulator
        builds (its obstacle and pushes; none by default)."""
        chosen = (
            experiment
            if experiment is None or isinstance(experiment, Experiment)
            else _experiment(experiment)
        )
        return RobotLoop(self.session, name, duration_s, chosen, out_dir)


def _experiment(name: str) -> Experiment:
    try:
        return get_experiment(name)
    except ValueError as exc:
        raise ConfigError(str(exc)) from None


class RobotLoop:
    """Your own 200 Hz loop, on the same spine as `hil run` (hil/loop/spine.py), as a context
    manager. Entering it opens the bus (and starts an embedded emulator), runs tick 0 (the
    start gate; torque on, holding the present position) and the configured hold ticks;
    then each cycle is yours:

        sample = loop.begin_cycle()     # the bus read once: a JointSample in SI units
        loop.cycle_actuation(goal)      # goal motor angles [rad] through the supervisor
        loop.end_cycle()                # the tick's record (reference and terms optional)

    or `for sample in loop: ... loop.cycle_actuation(goal)` (the cycle ends at the next
    iteration; a cycle without a goal holds the last one). Leaving the `with` block ends the
    run whatever happened: the stop cycles (the last goal held) when it ended normally, the
    configured exit torque state, the bus closed, summary.json written; `result` says how it
    ended. An exception of your code is recorded and re-raised (after torque off); Ctrl-C and
    SIGTERM end the iteration (`begin_cycle` raises `RunStopped`) and the run as interrupted;
    a lost bus ends it as a bus failure. The supervisor acts as in `hil run`: a latched
    torque_off turns torque off, and the run (a safety stop) goes on reading until you leave.

    >>> import hil
    >>> robot = hil.open_robot(robot="testbed", out_root="/tmp/hil-doctest")
    >>> with robot.loop("hold", duration_s=0.5) as loop:
    ...     for sample in loop:
    ...         sent = loop.cycle_actuation(sample.motor_angle_rad)
    >>> loop.result.exit_status, loop.result.ticks
    (0, 110)
    """

    def __init__(
        self,
        session: Session,
        name: str,
        duration_s: float | None,
        experiment: Experiment | None,
        out_dir: str | Path | None,
    ) -> None:
        if duration_s is not None and not (math.isfinite(duration_s) and duration_s > 0):
            raise ConfigError(f"duration_s must be a finite time > 0 s, got {duration_s}")
        self.session = session
        self.name = name
        self.duration_s = duration_s
        self.experiment = experiment
        self._out_dir = Path(out_dir) if out_dir is not None else None
        self._stack = contextlib.ExitStack()
        self._stop = StopFlag()
        self._spine: Spine | None = None
        self._clock: LoopClock | None = None
        self._first_tick = 0  # your first cycle's tick
        self._cycle_open = False
        self._started = 0.0
        self.result: RunResult | None = None

    # --- what you read -----------------------------------------------------------------------
    @property
    def state(self) -> SpineState:
        """The spine's state: the tick under way, its sample, the goal sent, the torque."""
        return self._running_spine.state

    @property
    def time_s(self) -> float:
        """Time since your first cycle [s] (the loop's grid: k x period)."""
        tick = self.state.tick
        return 0.0 if tick is None else (tick.index - self._first_tick) * self._clock_period

    @property
    def out_dir(self) -> Path:
        return self._running_spine.log.dir

    @property
    def supervisor_state(self) -> str:
        """'run', 'hold', 'back_off' or 'torque_off' (hil.safety.SafeState, lower case)."""
        return self._running_spine.supervisor.state.name.lower()

    # --- the cycle ---------------------------------------------------------------------------
    def begin_cycle(self) -> JointSample:
        """The next tick's reading (after the previous cycle's end); RunStopped once the loop's
        duration is over or Ctrl-C / SIGTERM came."""
        if self._cycle_open:
            self.end_cycle()
        if self._stop.reason is not None or self._past_duration():
            raise RunStopped(self._stop.reason or "the loop's duration is over")
        sample = self._running_spine.begin_cycle(self._next_tick())
        self._cycle_open = True
        return sample

    def cycle_actuation(self, goal_rad: np.ndarray | None) -> np.ndarray | None:
        """Send goal motor angles [rad] (one per joint) through the supervisor; returns what
        was sent (None: nothing, torque is off). None holds the last goal."""
        spine = self._running_spine
        if spine.state.goal is not None:
            raise RuntimeError("cycle_actuation() twice in one cycle")
        return spine.cycle_actuation(None if goal_rad is None else np.asarray(goal_rad, float))

    def end_cycle(
        self,
        reference_rad: np.ndarray | None = None,
        terms: Mapping[str, np.ndarray] | None = None,
    ) -> None:
        """The tick's record: `reference_rad` logged as the reference (NaN if None), `terms`
        are not logged by a loop of your own (log.csv has no term columns)."""
        spine = self._running_spine
        if spine.state.actuated < spine.state.read_done:  # no goal this cycle: hold
            spine.cycle_actuation(None)
        n = len(self.session.config.joints)
        reference = np.full(n, math.nan) if reference_rad is None else np.asarray(reference_rad)
        spine.end_cycle(reference, Phase.EXPERIMENT, None)
        self._cycle_open = False

    def __iter__(self) -> Iterator[JointSample]:
        while True:
            try:
                yield self.begin_cycle()
            except RunStopped:
                return

    # --- entering and leaving ----------------------------------------------------------------
    def __enter__(self) -> RobotLoop:
        session = self.session
        config = session.config
        self._started = time.perf_counter()
        try:
            self._stop.install()
            self._open(session, config)
            self._hold_ticks(config.loop.stop_cycles, Phase.HOLD)
        except BaseException as exc:
            self._leave(exc)
            raise
        self._first_tick = self._running_spine.state.ticks_done
        return self

    def _open(self, session: Session, config: Config) -> None:
        clock = session.clock()
        self._clock = clock
        out_dir = self._out_dir or create_run_dir(session.out_root, f"{timestamp()}-{self.name}")
        bus, connection = self._stack.enter_context(
            session.bus(self.experiment, (), clock, out_dir)
        )
        meta = {
            "experiment": self.name,
            "controller": "your loop",
            "setup": session.description,
            "clock": "lockstep" if clock.deterministic else "wall",
            "connection": connection,
            "bus": bus.describe(),
            "config_source": config.source,
            "config": config.record(),
        }
        columns = sensor_columns(config)
        log = open_run_log(out_dir, config.joint_names, meta, columns, mcap=True, term_columns=())
        supervisor = supervisor_for(config, bus.devices(), clock.period_s)
        record = RunRecord(log, columns, (), len(config.joints))
        self._spine = Spine(config, bus, clock, supervisor, log, record, say=None)
        self._spine.open()

    def _hold_ticks(self, ticks: int, phase: Phase) -> None:
        """Ticks of the spine's own: tick 0 and the hold at the start, the stop cycles at the
        end (the last goal held)."""
        spine = self._running_spine
        for _ in range(ticks):
            spine.begin_cycle(self._next_tick())
            spine.cycle_actuation(spine.state.last_goal if spine.started else None)
            n = len(self.session.config.joints)
            spine.end_cycle(np.full(n, math.nan), phase, None)

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> bool:
        return self._leave(exc)

    def _leave(self, exc: BaseException | None) -> bool:
        """Every exit path; True when `exc` was an ending of the run (not re-raised)."""
        spine, handled = self._spine, exc is None or isinstance(exc, RunStopped)
        try:
            if spine is not None:
                handled = self._end_run(spine, exc) or handled
        finally:
            self._stack.close()
            self._stop.restore()
        return handled

    def _end_run(self, spine: Spine, exc: BaseException | None) -> bool:
        state, handled = spine.state, False
        if isinstance(exc, Exception) and not isinstance(exc, RunStopped):
            handled = spine.ended_by(exc)
        elif isinstance(exc, KeyboardInterrupt):
            state.ending = RunEnding(Termination.INTERRUPTED, "KeyboardInterrupt")
        elif self._stop.reason is not None:
            state.ending = RunEnding(Termination.INTERRUPTED, self._stop.reason)
        if exc is None or isinstance(exc, RunStopped):
            with contextlib.suppress(*_ENDS):
                if self._cycle_open:
                    self.end_cycle()
                if spine.started and self._stop.reason is None:
                    self._hold_ticks(self.session.config.loop.stop_cycles, Phase.STOP)
        if state.ending.ok and spine.supervisor.first_trip is not None:
            first = spine.supervisor.first_trip
            state.ending = RunEnding(Termination.SAFETY_STOP, f"{first.cause} ({first.action})")
        self._write_summary(spine)
        return handled

    def _write_summary(self, spine: Spine) -> None:
        state = spine.state
        try:
            spine.record.write_kept()
        except LogWriterLost as lost:
            if state.ending.ok:
                state.ending = RunEnding(Termination.BUS_FAILURE, str(lost))
        notes = spine.close()
        wall = time.perf_counter() - self._started
        summary = {
            "experiment": self.name,
            "controller": "your loop",
            "termination": state.ending.text,
            "ticks": state.ticks_done,
            "wall_time_s": wall,
            "exit": notes,
            **spine.safety_summary(),
            "current_limit_a": spine.current_limits,
            "metrics": {},
        }
        spine.log.write_summary(summary)
        spine.log.close()
        self.result = RunResult(
            spine.log.dir,
            state.ending,
            {},
            list(spine.supervisor.events),
            state.ticks_done,
            wall,
            tuple(notes),
            spine.torque.exit_failed,
        )

    # --- inside ------------------------------------------------------------------------------
    @property
    def _running_spine(self) -> Spine:
        if self._spine is None:
            raise RuntimeError("use the loop in a `with` block: `with robot.loop() as loop:`")
        return self._spine

    @property
    def _clock_period(self) -> float:
        assert self._clock is not None
        return self._clock.period_s

    def _next_tick(self) -> Tick:
        assert self._clock is not None
        tick = self._clock.next_tick()
        return tick

    def _past_duration(self) -> bool:
        if self.duration_s is None or self._spine is None:
            return False
        done = self._spine.state.ticks_done - self._first_tick
        return done * self._clock_period >= self.duration_s - 1e-9


# what ends a run's stop cycles early without being an error of the caller's
_ENDS = (RunStopped, OSError, LogWriterLost)
