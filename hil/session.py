"""Where a run happens and what the user sees: emulator lifetime, clocks, output, the report.

Three setups, one code path for the loop:
    embedded (no --config, or --emulate)  a fresh `hil emulate` child per run, lock-step clock
                                          (deterministic) or, with --realtime, wall clock
    attached (--attach JSON)              a `hil emulate` someone started: wall clock
    hardware (--config FILE [--port ...]) the ports FILE names (or the overrides): wall clock
"""

from __future__ import annotations

import contextlib
import json
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any

from hil.clock import LockstepClock, LoopClock, WallClock
from hil.config import Config
from hil.emulation import EmbeddedEmulator, EmulatorStartError, emulator_spec
from hil.experiments import EXPERIMENTS, Experiment
from hil.hardware import Connection, make_bus
from hil.runner import RunRequest, RunResult, StopFlag, run_experiment
from sim_backend.scenario import FaultEvent

COMPARISON_CONTROLLERS: tuple[tuple[str, float], ...] = (
    ("pid", 0.0),
    ("gc", 0.0),
    ("gc+lqr", 0.0),
    ("gc+lqr+dob", 0.5),
    ("gc+lqr+dob", 1.0),
)
# The comparison also runs the DOB controller once with the other reading of (25), so that the
# report shows what the choice of reading does (DESIGN.md: the lab's accumulated total vs the
# literal uc(tk - dt)). Its rows are keyed "gc+lqr+dob/<reading>".
OTHER_READING_KDIST = 1.0


# How a run can end without having run its course (a safety stop is a result, not these).
INCOMPLETE = ("interrupted", "start refused", "bus failure", "error")


class SessionError(RuntimeError):
    """A run could not start (emulator, ports): the message says what to check."""


def run_label(controller: str, kdist: float) -> str:
    """'gc+lqr+dob (Kdist 1)'; a controller key 'gc+lqr+dob/literal' adds its reading of (25)."""
    base, _, reading = controller.partition("/")
    label = f"{base} (Kdist {kdist:g})" if base == "gc+lqr+dob" else base
    return f"{label}, {reading} (25)" if reading else label


@dataclass
class Session:
    config: Config
    embedded: bool
    realtime: bool = False
    attach: dict[str, Any] | None = None
    connection_overrides: dict[str, Any] | None = None
    seed: int | None = None
    out_root: Path = Path("runs")
    plots: bool = True
    json_output: bool = False
    quiet: bool = False

    @property
    def setup(self) -> str:
        if self.embedded:
            return "emulated testbed, " + ("real time" if self.realtime else "lock-step")
        if self.attach is not None:
            return f"attached emulator {self.attach.get('dynamixel_port')}"
        return f"hardware {self.config.dynamixel.port}"

    def _say(self, text: str) -> None:
        if not self.quiet:
            print(text, file=sys.stderr, flush=True)

    @contextlib.contextmanager
    def _connection(
        self, experiment: Experiment, faults: tuple[FaultEvent, ...]
    ) -> Iterator[Connection]:
        overrides = {k: v for k, v in (self.connection_overrides or {}).items() if v}
        if self.embedded:
            spec = emulator_spec(
                self.config,
                experiment=experiment,
                faults=faults,
                clock="realtime" if self.realtime else "lockstep",
                seed=self.seed,
            )
            emulator = EmbeddedEmulator(spec)
            try:
                try:
                    endpoints = emulator.start()
                except EmulatorStartError as exc:
                    raise SessionError(f"could not start the emulated testbed: {exc}") from exc
                yield Connection.from_endpoints(endpoints)
            finally:
                emulator.stop()  # also after Ctrl-C during start-up: no child left behind
        elif self.attach is not None:
            yield Connection.from_endpoints(self.attach).with_overrides(**overrides)
        else:
            yield Connection.from_config(self.config).with_overrides(**overrides)

    def _clock(self) -> LoopClock:
        period = self.config.loop.period_s
        if self.embedded and not self.realtime:
            return LockstepClock(period)
        return WallClock(period)

    def run_one(
        self,
        experiment: Experiment,
        controller: str,
        kdist: float,
        *,
        faults: tuple[FaultEvent, ...] = (),
        overruns: tuple[tuple[float, float], ...] = (),
        duration_s: float | None = None,
        reboot_first: bool = False,
        out_dir: Path | None = None,
        print_result: bool = True,
        stop: StopFlag | None = None,
    ) -> RunResult:
        label = run_label(controller, kdist)
        literal = self.config.controller.composition == "literal" and "lqr" in controller
        if literal and "literal" not in label:
            label += ", literal (25)"
        if out_dir is None:
            stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
            name = f"{stamp}-{experiment.name}-{controller.replace('+', '-')}"
            if controller == "gc+lqr+dob":
                name += f"-k{kdist:g}"
            if literal:
                name += "-literal"
            out_dir = _unique(self.out_root / name)
        request = RunRequest(
            experiment=experiment,
            controller=controller,
            kdist=kdist,
            out_dir=out_dir,
            duration_s=duration_s,
            overruns=overruns,
            reboot_first=reboot_first,
            progress=not self.quiet,
        )
        clock = self._clock()
        meta = self._meta(experiment, controller, kdist, faults, overruns, clock)
        self._say(f"hil run: {experiment.name} with {label} on the {self.setup} -> {out_dir}")
        with self._connection(experiment, faults) as connection:
            bus_clock = clock.now if isinstance(clock, LockstepClock) else time.monotonic
            bus = make_bus(self.config, connection, clock=bus_clock)
            result = run_experiment(
                self.config,
                request,
                bus,
                clock,
                meta,
                on_progress=self._progress(label),
                stop=stop,
            )
        if self.plots and result.ticks > 1:
            from hil.plots import plot_run

            try:
                plot_run(out_dir, experiment)
            except Exception as exc:  # noqa: BLE001 - a plot must not lose a run
                self._say(f"  (plot failed: {exc})")
        if print_result:
            self._print_result(experiment, label, result)
        return result

    def _progress(self, label: str):  # noqa: ANN202
        def report(time_s: float, total_s: float) -> None:
            if not self.quiet and sys.stderr.isatty():
                print(f"\r  {label}: {time_s:5.1f} / {total_s:.1f} s", end="", file=sys.stderr)
                if time_s + 1.0 > total_s:
                    print(file=sys.stderr)

        return report

    def _meta(
        self,
        experiment: Experiment,
        controller: str,
        kdist: float,
        faults: tuple[FaultEvent, ...],
        overruns: tuple[tuple[float, float], ...],
        clock: LoopClock,
    ) -> dict[str, Any]:
        import platform

        from hil.versions import package_versions

        return {
            "experiment": experiment.name,
            "experiment_title": experiment.title,
            "controller": controller,
            "kdist": kdist,
            "setup": self.setup,
            "clock": "lockstep" if clock.deterministic else "wall",
            "seed": self.seed if self.seed is not None else self.config.emulator.seed,
            "faults": [vars(f) for f in faults],
            "overruns": list(overruns),
            "config_source": self.config.source,
            "config": _config_dict(self.config),
            "started": datetime.now().isoformat(timespec="seconds"),
            "python": platform.python_version(),
            "packages": package_versions(),
        }

    def _print_result(self, experiment: Experiment, label: str, result: RunResult) -> None:
        metrics = {k: v for k, v in result.metrics.items()}
        shown = ", ".join(f"{k} = {_fmt(v)}" for k, v in metrics.items())
        print(f"{experiment.name} / {label}: {result.termination}")
        if shown:
            print(f"  {shown}")
        for event in result.safety_events:
            print(f"  safety: t = {event.time_s:.3f} s {event.cause} -> {event.action}")
        print(
            f"  log: {result.out_dir / 'log.csv'}  "
            f"({result.ticks} ticks, {result.wall_time_s:.1f} s)"
        )
        if self.json_output:
            print(
                json.dumps(
                    {
                        "experiment": experiment.name,
                        "controller": label,
                        "termination": result.termination,
                        "out_dir": str(result.out_dir),
                        **metrics,
                    },
                    default=str,
                )
            )

    # --- the whole comparison ----------------------------------------------------------------
    def run_comparison(
        self,
        *,
        faults: tuple[FaultEvent, ...] = (),
        overruns: tuple[tuple[float, float], ...] = (),
        current_guard: bool = False,
        stop: StopFlag | None = None,
    ) -> RunResult:
        """Both experiments x the paper's controllers, then one report.

        The software current guard is off unless asked for: the paper's experiment shows the
        actuator's own overload protection acting, and the guard would pre-empt it.
        """
        import dataclasses

        from hil.report import write_report

        safety = dataclasses.replace(self.config.safety, current_guard=current_guard)
        self.config = self.config.with_overrides(safety=safety)

        stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
        root = _unique(self.out_root / f"{stamp}-comparison")
        default_reading = self.config.controller.composition
        other_reading = "literal" if default_reading == "accumulated" else "accumulated"
        entries = [*COMPARISON_CONTROLLERS, (f"gc+lqr+dob/{other_reading}", OTHER_READING_KDIST)]
        plan = [
            (experiment, controller, kdist)
            for experiment in EXPERIMENTS.values()
            for controller, kdist in entries
        ]
        results: list[tuple[Experiment, str, float, RunResult]] = []
        started = time.perf_counter()
        default_config = self.config
        interrupted: str | None = None
        for number, (experiment, key, kdist) in enumerate(plan, start=1):
            if stop is not None and stop.reason is not None:
                interrupted = stop.reason
                break
            self._say(f"[{number}/{len(plan)}] {experiment.name}: {run_label(key, kdist)}")
            controller, _, reading = key.partition("/")
            name = f"{experiment.name}-{controller.replace('+', '-')}"
            if controller == "gc+lqr+dob":
                name += f"-k{kdist:g}"
            if reading:
                name += f"-{reading}"
                section = dataclasses.replace(default_config.controller, composition=reading)
                self.config = default_config.with_overrides(controller=section)
            try:
                result = self.run_one(
                    experiment,
                    controller,
                    kdist,
                    faults=faults,
                    overruns=overruns,
                    out_dir=root / name,
                    print_result=False,
                    stop=stop,
                )
            finally:
                self.config = default_config
            results.append((experiment, key, kdist, result))
            if result.termination.startswith(INCOMPLETE):
                interrupted = interrupted or f"{experiment.name} / {key}: {result.termination}"
                if result.termination.startswith("interrupted"):
                    break
        report = write_report(root, results, self.setup, time.perf_counter() - started)
        print(report.table_text)
        print(f"report: {report.markdown_path}")
        if self.json_output:
            print(json.dumps(report.summary, default=str))
        if interrupted is not None:
            print(f"comparison incomplete: {interrupted}")
        return RunResult(root, "completed" if interrupted is None else interrupted, {})


def _unique(path: Path) -> Path:
    candidate, n = path, 1
    while candidate.exists():
        n += 1
        candidate = path.with_name(f"{path.name}-{n}")
    return candidate


def _fmt(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def _config_dict(config: Config) -> dict[str, Any]:
    import dataclasses

    return dataclasses.asdict(config)
