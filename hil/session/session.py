"""Where a run happens and what the user sees: emulator lifetime, clocks, the run's record.

Four setups, one code path for the loop:
    embedded (no --config, or --emulate)  a fresh `hil emulate` child per run, lock-step clock
                                          (deterministic) or, with --realtime, wall clock
    in_process                            the emulated robot in this process, no buses
                                          (hil.wiring.in_process): lock-step, for tests and
                                          sweeps that need throughput
    attached (--attach JSON)              a `hil emulate` someone started: lock-step when it
                                          is (its JSON line says), else wall clock
    hardware (--config FILE [--port ...]) the ports FILE names (or the overrides): wall clock
"""

from __future__ import annotations

import contextlib
import enum
import os
import platform
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any

from controller import CompositionReading
from drivers.joint_bus import JointBus
from hil.config import Config
from hil.experiments import Experiment
from hil.loop import LockstepClock, LoopClock, RunRequest, StopFlag, WallClock, run_experiment
from hil.output.channels import MessageSink
from hil.output.plots import plot_run
from hil.output.progress import Progress
from hil.output.records import UNMEASURED, RunResult
from hil.output.ros2_bag import ROS2_BAG_NAME
from hil.output.rundir import add_to_summary, create_run_dir, load_run, timestamp
from hil.output.series import write_series
from hil.output.strict_json import dumps
from hil.output.versions import package_versions
from hil.output.views import ROS2_BAG_KEY
from hil.robots import profile_of
from hil.vocabulary import ControllerChoice, EmulatorClock
from hil.wiring import Connection, make_bus
from hil.wiring.emulation import EmbeddedEmulator, EmulatorStartError, emulator_spec
from hil.wiring.in_process import in_process_bus
from sim_backend.scenario import FaultEvent
from sim_backend.truth_log import TRUTH_LOG_NAME


class SessionError(RuntimeError):
    """A run could not start (emulator, ports): the message says what to check."""


class Setup(enum.StrEnum):
    EMBEDDED = "embedded"
    IN_PROCESS = "in_process"
    ATTACHED = "attached"
    HARDWARE = "hardware"

    @property
    def emulated(self) -> bool:
        return self is not Setup.HARDWARE


@dataclass(frozen=True)
class ConnectionOverrides:
    """--port / --baudrate / --can-interface / --can-channel, as given (None: not given)."""

    port: str | None = None
    baudrate: int | None = None
    can_interface: str | None = None
    can_channel: str | None = None

    @property
    def given(self) -> dict[str, Any]:
        return {k: v for k, v in vars(self).items() if v}


@dataclass
class Session:
    config: Config
    setup: Setup
    realtime: bool = False
    attach: dict[str, Any] | None = None
    overrides: ConnectionOverrides = field(default_factory=ConnectionOverrides)
    seed: int | None = None
    out_root: Path = Path("runs")
    plots: bool = True
    json_output: bool = False
    quiet: bool = False
    mcap: bool = True  # run.mcap beside the CSV log
    ros2: bool = False  # run.ros2.mcap, a ROS 2 bag, beside it (hil/output/views.py)
    # A bar over several runs (the comparison): lines go above it, a run's progress moves it
    # from `progress_done` (runs finished) towards the next whole run.
    progress: Progress | None = None
    progress_done: float = 0.0
    sinks: tuple[MessageSink, ...] = ()  # the live view (`hil run --live`), owned by the caller
    # what the last embedded emulator said its injected faults did (see `_record_fault_counts`)
    emulator_fault_counts: dict[str, Any] = field(default_factory=dict)

    @property
    def description(self) -> str:
        emulated = profile_of(self.config).emulated
        gc = f"GC compliance: {self.config.controller.gc_compliance}"
        if self.setup is Setup.EMBEDDED:
            return f"{emulated}, " + ("real time" if self.realtime else "lock-step") + f"; {gc}"
        if self.setup is Setup.IN_PROCESS:
            return f"{emulated} in process, lock-step; {gc}"
        if self.setup is Setup.ATTACHED:
            return f"attached emulator {(self.attach or {}).get('dynamixel_port')}; {gc}"
        return "hardware " + ", ".join(d.port for d in self.config.dynamixel) + f"; {gc}"

    def say(self, text: str) -> None:
        if self.quiet:
            return
        if self.progress is not None:
            self.progress.write(text)
        else:
            print(text, file=sys.stderr, flush=True)

    @contextlib.contextmanager
    def bus(
        self,
        experiment: Experiment | None,
        faults: tuple[FaultEvent, ...],
        clock: LoopClock,
        out_dir: Path | None = None,
    ) -> Iterator[tuple[JointBus, dict[str, Any]]]:
        """The bus of this setup for one run, and what it connects to (an embedded emulator
        lives as long as the run and writes its ground truth into `out_dir`)."""
        if self.setup is Setup.IN_PROCESS:
            bus = in_process_bus(self.config, experiment, faults, seed=self.seed)
            yield bus, {"in_process": True}
            return
        bus_clock = clock.now if isinstance(clock, LockstepClock) else time.monotonic
        with self.connection(experiment, faults, out_dir) as connection:
            yield make_bus(self.config, connection, clock=bus_clock), connection.record()

    @contextlib.contextmanager
    def connection(
        self,
        experiment: Experiment | None,
        faults: tuple[FaultEvent, ...] = (),
        out_dir: Path | None = None,
    ) -> Iterator[Connection]:
        """The buses of this setup (an embedded emulator lives as long as the context)."""
        overrides = self.overrides.given
        if self.setup is Setup.EMBEDDED:
            if out_dir is not None:  # a planned run's directory is named, not yet made
                out_dir.mkdir(parents=True, exist_ok=True)
            spec = emulator_spec(
                self.config,
                experiment=experiment,
                faults=faults,
                clock=EmulatorClock.REALTIME if self.realtime else EmulatorClock.LOCKSTEP,
                seed=self.seed,
                truth_log=out_dir / TRUTH_LOG_NAME if out_dir is not None else None,
            )
            emulator = EmbeddedEmulator(spec)
            try:
                try:
                    endpoints = emulator.start()
                except EmulatorStartError as exc:
                    raise SessionError(f"could not start the emulator: {exc}") from exc
                yield Connection.from_endpoints(endpoints, self.config)
            finally:
                emulator.stop()  # also after Ctrl-C during start-up: no child left behind
                self.emulator_fault_counts = emulator.fault_counts
        elif self.setup is Setup.ATTACHED:
            assert self.attach is not None
            yield Connection.from_endpoints(self.attach, self.config).with_overrides(**overrides)
        elif self.setup is Setup.HARDWARE:
            yield Connection.from_config(self.config).with_overrides(**overrides)
        else:
            raise SessionError(f"the {self.setup} setup has no connection")

    def clock(self) -> LoopClock:
        period = self.config.loop.period_s
        # an attached lock-step emulator advances one period per SYNC: pacing the loop with
        # the wall clock there would only count a slow machine's ticks as overruns
        attached_lockstep = (
            self.setup is Setup.ATTACHED
            and (self.attach or {}).get("clock") == EmulatorClock.LOCKSTEP
        )
        lockstep = self.setup is Setup.IN_PROCESS or (
            self.setup in (Setup.EMBEDDED, Setup.ATTACHED)
            and not self.realtime
            and (self.setup is Setup.EMBEDDED or attached_lockstep)
        )
        if lockstep:
            return LockstepClock(period)
        return WallClock(period, spin_s=self.config.loop.spin_before_tick_s)

    def labelled(self, choice: ControllerChoice) -> ControllerChoice:
        """The choice with its reading of (25) named when the configuration's is not the lab's
        default (so that the label and the directory say so)."""
        composition = self.config.controller.composition
        lab = CompositionReading.ACCUMULATED
        if choice.reading is None and composition != lab and choice.ref.has_composition:
            return choice.with_reading(composition)
        return choice

    def run_one(
        self,
        experiment: Experiment,
        choice: ControllerChoice,
        *,
        faults: tuple[FaultEvent, ...] = (),
        overruns: tuple[tuple[float, float], ...] = (),
        duration_s: float | None = None,
        reboot_first: bool = False,
        out_dir: Path | None = None,
        print_result: bool = True,
        stop: StopFlag | None = None,
    ) -> RunResult:
        choice = self.labelled(choice)
        created = out_dir is None
        if out_dir is None:  # its own, created now: a run started at the same time gets another
            out_dir = create_run_dir(
                self.out_root, f"{timestamp()}-{experiment.name}-{choice.dir_name}"
            )
        request = RunRequest(
            experiment=experiment,
            choice=choice,
            out_dir=out_dir,
            duration_s=duration_s,
            overruns=overruns,
            reboot_first=reboot_first,
            on_event=None if self.quiet else self.say,
            on_progress=self._progress(choice.label),
            mcap=self.mcap,
            sinks=self.sinks,
        )
        clock = self.clock()
        self.say(
            f"hil run: {experiment.name} with {choice.label} on the {self.description} -> {out_dir}"
        )
        self.emulator_fault_counts = {}
        try:
            with self.bus(experiment, faults, clock, out_dir) as (bus, connection):
                meta = self._meta(experiment, choice, faults, overruns, clock, connection)
                meta["bus"] = bus.describe()
                if self.ros2:
                    meta[ROS2_BAG_KEY] = ROS2_BAG_NAME
                result = run_experiment(self.config, request, bus, clock, meta, stop=stop)
        except BaseException:
            if created:  # the run never began (the emulator did not start): no empty directory
                with contextlib.suppress(OSError):
                    out_dir.rmdir()
            raise
        if result.torque_off_failed:
            warn_torque_not_off(result)
        if faults:
            self._record_fault_counts(out_dir, faults)
        if self.ros2 and (out_dir / TRUTH_LOG_NAME).is_file():
            self._bag_with_the_truth(out_dir)
        if result.ticks > 1:
            self._write_derived_series(experiment, out_dir)
        if self.plots and result.ticks > 1:
            try:
                run = load_run(out_dir)
                plot_run(run, experiment.marks(run))
            except Exception as exc:  # noqa: BLE001 - a plot must not lose a run
                self.say(f"  (plot failed: {exc})")
        if print_result:
            self._print_result(experiment, choice, result)
        return result

    def _bag_with_the_truth(self, out_dir: Path) -> None:
        """The finished run's ROS 2 bag made again from its record, with the humanoid's base
        from the emulator's truth (the bag written during the run has the leg odometry: the
        truth is the emulator's own file, complete only once it has stopped). Written beside
        and then put in place: a failure leaves the run's own bag as it was, and says so."""
        from hil.output.ros2_export import export_ros2

        bag = out_dir / ROS2_BAG_NAME
        whole = bag.with_name(f".{bag.name}.with-truth")
        try:
            export_ros2(out_dir, whole)
            os.replace(whole, bag)
        except Exception as exc:  # noqa: BLE001 - the bag written during the run stays
            whole.unlink(missing_ok=True)
            self.say(
                "  (the ROS 2 bag keeps the leg odometry for the base: "
                f"{type(exc).__name__}: {exc})"
            )

    def _write_derived_series(self, experiment: Experiment, out_dir: Path) -> None:
        """The experiment's per-tick series beside log.csv (kinematics.csv on the humanoid:
        hil/output/series.py), from the finished run's record."""
        try:
            series = experiment.derived_series(load_run(out_dir))
            if series is not None:
                write_series(out_dir, series)
        except Exception as exc:  # noqa: BLE001 - a derived file must not lose a run
            self.say(f"  (the per-tick series failed: {type(exc).__name__}: {exc})")

    def _record_fault_counts(self, out_dir: Path, faults: tuple[FaultEvent, ...]) -> None:
        """What the emulator says its injected faults did, into summary.json; a fault that never
        acted (after the run's end, or on a part the run never touched) is said out loud."""
        counts = self.emulator_fault_counts
        if not counts:
            return
        add_to_summary(out_dir, "emulator_fault_counts", counts)
        started = set(counts.get("scenario_faults_started", []))
        for number, fault in enumerate(faults):
            if number not in started:
                self.say(f"  note: the injected fault {fault.kind}@{fault.start_s:g} never acted")

    def _progress(self, label: str) -> Callable[[float, float], None]:
        def report(time_s: float, total_s: float) -> None:
            if self.progress is not None:
                fraction = min(time_s / total_s, 1.0) if total_s > 0 else 0.0
                self.progress.update_to(self.progress_done + fraction, label)
            elif not self.quiet and sys.stderr.isatty():
                print(f"\r  {label}: {time_s:5.1f} / {total_s:.1f} s", end="", file=sys.stderr)
                if time_s + 1.0 > total_s:
                    print(file=sys.stderr)

        return report

    def _meta(
        self,
        experiment: Experiment,
        choice: ControllerChoice,
        faults: tuple[FaultEvent, ...],
        overruns: tuple[tuple[float, float], ...],
        clock: LoopClock,
        connection: dict[str, Any],
    ) -> dict[str, Any]:
        return {
            "experiment": experiment.name,
            "experiment_title": experiment.title,
            "experiment_parameters": experiment.parameters(),
            "controller": choice.name,
            "controller_label": choice.label,
            # where it was loaded from ("file:/abs/path.py:Class" for a plug-in) and its own
            # parameters ([controller.params]; the paper's are in `config`)
            "controller_spec": choice.ref.spec,
            "controller_params": dict(self.config.controller.params),
            "kdist": choice.kdist,
            "reading": choice.reading,
            "gc_compliance": str(choice.gc_compliance or self.config.controller.gc_compliance),
            "setup": self.description,
            "clock": "lockstep" if clock.deterministic else "wall",
            "seed": self.seed if self.seed is not None else self.config.emulator.seed,
            "faults": [vars(f) for f in faults],
            "overruns": list(overruns),
            "connection": connection,
            "config_source": self.config.source,
            "config": self.config.record(),
            "started": datetime.now().isoformat(timespec="seconds"),
            "python": platform.python_version(),
            "packages": package_versions(),
        }

    def _print_result(
        self, experiment: Experiment, choice: ControllerChoice, result: RunResult
    ) -> None:
        unmeasured = result.metrics.get(UNMEASURED) or {}
        shown = ", ".join(
            f"{k} = {_fmt(v)}"
            for k, v in result.metrics.items()
            if k != UNMEASURED and k not in unmeasured
        )
        print(f"{experiment.name} / {choice.label}: {result.ending}")
        if shown:
            print(f"  {shown}")
        for key, why in unmeasured.items():
            print(f"  {key}: not measured ({why})")
        for event in result.safety_events:
            print(f"  safety: t = {event.time_s:.3f} s {event.cause} -> {event.action}")
        run_time_s = result.ticks * self.config.loop.period_s
        print(
            f"  log: {result.out_dir / 'log.csv'}  ({result.ticks} ticks = {run_time_s:.2f} s "
            f"of run time, in {result.wall_time_s:.1f} s on the wall clock)"
        )
        if self.json_output:
            record = {
                "experiment": experiment.name,
                "controller": choice.label,
                "termination": result.ending.text,
                "out_dir": str(result.out_dir),
                "exit": list(result.exit_notes),
                "torque_off_failed": result.torque_off_failed,
                **result.metrics,
            }
            print(dumps(record))


def warn_torque_not_off(result: RunResult) -> None:
    """Said on stderr whatever else is quiet: the actuators may still hold with torque on."""
    print(
        f"hil run: WARNING: TORQUE COULD NOT BE TURNED OFF at the end of the run "
        f"({result.ending}; {'; '.join(result.exit_notes)}). The actuators did not take "
        "Torque Enable = 0: they may still hold their last goal with torque on. Cut their "
        f"power (emergency stop) before going near the robot. Details: "
        f"{result.out_dir / 'events.jsonl'}",
        file=sys.stderr,
        flush=True,
    )


def _fmt(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)
