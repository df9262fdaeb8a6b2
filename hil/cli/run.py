"""`hil run [EXPERIMENT] ...`: one experiment, or without one the paper's testbed comparison."""

from __future__ import annotations

import argparse
import math
import os
import shutil
import sys
import tempfile
import tomllib
from pathlib import Path

from hil.cli.common import checked_config, connection_overrides, load_attach, parse_injections
from hil.cli.design import check_designs, comparison_runs
from hil.cli.exit_codes import ExitCode
from hil.config import Config, ConfigError, robot_of
from hil.controllers import ControllerLoadError
from hil.controllers.choice import choose
from hil.experiments import Experiment
from hil.loop import StopFlag, duration_problem
from hil.output.channels import MessageSink
from hil.output.rundir import describe_bytes, estimated_record_bytes
from hil.robots import NAMED_COMPARISONS, get_experiment
from hil.safety import ReferenceOutsideLimits
from hil.session import Session, SessionError, Setup, run_comparison
from hil.vocabulary import ControllerChoice, ControllerKind

_SINGLE_RUN_OPTIONS = (
    ("--controller", "controller"),
    ("--kdist", "kdist"),
    ("--composition", "composition"),
    ("--duration", "duration"),
    ("--reboot-first", "reboot_first"),
)
_COMPARISON_OPTIONS = (("--workers", "workers"),)


def _configured(args: argparse.Namespace) -> Config:
    """The configuration with the command line's changes, each validated like the file."""
    config = checked_config(args.config, args.robot, args.experiment)
    if args.composition is not None:
        config = config.changed("controller", composition=args.composition, option="--composition")
    if args.kdist is not None:
        config = config.changed("controller", kdist=args.kdist, option="--kdist")
    if args.gc_compliance is not None:
        config = config.changed(
            "controller", gc_compliance=args.gc_compliance, option="--gc-compliance"
        )
    if args.current_guard is not None:
        config = config.changed(
            "safety", current_guard=args.current_guard == "on", option="--current-guard"
        )
    if args.seed is not None:
        config.changed("emulator", seed=args.seed, option="--seed")  # validated, used below
    if args.param:
        params = {**config.controller.params, **_params(args.param)}
        config = config.changed("controller", params=params, option="--param")
    return config


def _params(items: list[str]) -> dict[str, object]:
    """--param KEY=VALUE ..., each VALUE read as TOML; a bare word is text (also nan and inf,
    which no parameter takes as a number)."""
    params: dict[str, object] = {}
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or not key.strip().isidentifier():
            raise ConfigError(f"--param {item!r}: give KEY=VALUE, e.g. --param kp=0.5")
        try:
            value = tomllib.loads(f"v = {text.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            value = text.strip()
        if isinstance(value, float) and not math.isfinite(value):
            value = text.strip()
        params[key.strip()] = value
    return params


def _check_combinations(args: argparse.Namespace, embedded: bool, faults: tuple) -> None:
    overrides = connection_overrides(args).given
    if args.attach and args.emulate:
        raise ConfigError(
            "--attach and --emulate exclude each other: attach to a running `hil emulate`, or "
            "let `hil run` start its own"
        )
    if overrides and args.config is None and not args.attach:
        raise ConfigError(
            f"{', '.join('--' + k.replace('_', '-') for k in overrides)} points a hardware "
            "configuration at other ports: give --config FILE (or --attach for an emulator)"
        )
    if args.experiment is not None:
        ignored = [o for o, key in _COMPARISON_OPTIONS if getattr(args, key) is not None]
        if ignored:
            raise ConfigError(
                f"{', '.join(ignored)} applies to the comparison (`hil run` with no experiment, "
                "or `hil run walking`), which runs several experiments; one runs alone"
            )
    if args.experiment is None:
        ignored = [option for option, key in _SINGLE_RUN_OPTIONS if getattr(args, key)]
        if ignored:
            raise ConfigError(
                f"{', '.join(ignored)} apply to one experiment; the comparison (no experiment) "
                "runs its own plan: name an experiment (contact or impact)"
            )
        if not embedded and args.attach is None:
            raise ConfigError(
                "the comparison drives `pid` into the block until the actuator's overload "
                "protection trips: it runs only on an emulated testbed (no --config, --emulate, "
                "or --attach). On hardware, run one experiment at a time: hil run contact "
                "--config ..."
            )
    if faults and not embedded:
        raise ConfigError(
            "--inject of an emulator fault needs the embedded emulator (no --config, or "
            "--emulate); for a separate `hil emulate`, pass --inject to it"
        )
    if args.duration is not None and (problem := duration_problem(args.duration)) is not None:
        raise ConfigError(f"--duration: {problem}")


def _check_ros2(args: argparse.Namespace) -> None:
    """--ros2: the `ros2` extra installed, said before anything starts."""
    if not args.ros2:
        return
    from hil.output.ros2_bag import MISSING_EXTRA, ros2_support_installed

    if not ros2_support_installed():
        raise ConfigError(f"--ros2: {MISSING_EXTRA}")


def _live(args: argparse.Namespace) -> tuple[MessageSink, ...]:
    """--live: the Foxglove WebSocket server (loopback unless --live-host names another)."""
    if not args.live:
        return ()
    if not 0 <= args.live_port <= 65535:
        raise ConfigError(f"--live-port: must be in 0..65535, got {args.live_port}")
    from hil.output.live import LivePublisher

    try:
        publisher = LivePublisher(args.live_host, args.live_port)
    except Exception as exc:  # the SDK raises its own error types: say what it said
        raise ConfigError(
            f"--live: cannot listen on {args.live_host}:{args.live_port}: {exc}"
        ) from exc
    print(
        f"hil run: live view on {publisher.url} (Foxglove: Open connection > Foxglove WebSocket)",
        file=sys.stderr,
    )
    return (publisher,)


def _check_timeline(args: argparse.Namespace, faults: tuple, overruns: tuple) -> None:
    """Refuse what would silently not happen: a fault after the run's end, an attached emulator
    built for another experiment's world."""
    if args.experiment is None:
        return
    duration = args.duration or get_experiment(args.experiment).duration_s
    late = [f"{f.kind}@{f.start_s:g}" for f in faults if f.start_s >= duration]
    late += [f"overrun@{start:g}" for start, _ in overruns if start >= duration]
    if late:
        raise ConfigError(
            f"--inject {', '.join(late)}: after the run's end ({duration:g} s): it would never "
            "happen"
        )
    if args.attach:
        attached = load_attach(args.attach)
        if "experiment" in attached and attached["experiment"] != args.experiment:
            raise ConfigError(
                f"--attach: that emulator was started for experiment "
                f"{attached['experiment']!r}, not {args.experiment!r}: its world (block, pushes) "
                f"is not this run's; start it with `hil emulate --experiment {args.experiment}`"
            )


def _choice(args: argparse.Namespace, config: Config, experiment: Experiment) -> ControllerChoice:
    """The controller of a single run (a registry name or a plug-in, resolved, its parameters
    and a plug-in's first steps checked now: hil/controllers/choice.py); an open-loop
    experiment (identify) has none: the actuator's own position control follows its goals,
    which is what `pid` names."""
    if not experiment.open_loop:
        given = "--controller" if args.controller else f"{config.source} [controller] name"
        try:
            choice = choose(args.controller or config.controller.name, config, experiment)
        except ControllerLoadError as exc:
            raise ConfigError(f"{given}: {exc}") from None
        _check_choice(args, config, choice)
        return choice
    if args.controller not in (None, str(ControllerKind.PID)) or args.kdist is not None:
        raise ConfigError(
            f"{experiment.name} runs open loop (its own goals, no controller): drop --controller "
            "and --kdist"
        )
    return ControllerChoice(ControllerKind.PID)


def _check_choice(args: argparse.Namespace, config: Config, choice: ControllerChoice) -> None:
    """What the controller would ignore, or the supervisor refuse at the first tick with torque
    on (gain_out_of_range), judged now."""
    name = choice.name
    if args.kdist is not None and not choice.uses_kdist:
        raise ConfigError(
            f"--kdist is the DOB's gain: {name} has no DOB (give a controller with one, e.g. "
            f"--controller {ControllerKind.GC_LQR_DOB}, or drop --kdist)"
        )
    if args.composition is not None and not choice.ref.has_composition:
        raise ConfigError(
            f"--composition is a reading of (25), the LQR's composition: {name} has no LQR"
        )
    max_kdist = config.safety.max_kdist
    if choice.uses_kdist and choice.kdist > max_kdist:
        given = "--kdist" if args.kdist is not None else f"{config.source} [controller] kdist"
        raise ConfigError(
            f"{given} = {choice.kdist:g} is above [safety] max_kdist = {max_kdist:g}, beyond the "
            "paper's gains and the closed-loop analysis (docs/safety.md): raise max_kdist "
            "knowingly to run it"
        )


def _check_out(args: argparse.Namespace, config: Config) -> None:
    """--out: a directory this process can create run directories in, with room for the run's
    record: refused now, before a run directory is named."""
    out: Path = args.out
    if out.exists() and not out.is_dir():
        raise ConfigError(f"--out {out}: is a file, not a directory")
    try:
        out.mkdir(parents=True, exist_ok=True)
        os.rmdir(tempfile.mkdtemp(prefix=".hil-write-check-", dir=out))
    except OSError as exc:
        raise ConfigError(f"--out {out}: cannot write run directories there: {exc}") from None
    if args.experiment is None:
        return
    duration = args.duration or get_experiment(args.experiment).duration_s
    ticks = int(duration * config.loop.rate_hz) + config.loop.stop_cycles
    need = estimated_record_bytes(ticks, len(config.joints), mcap=not args.no_mcap)
    free = shutil.disk_usage(out).free
    if need > free:
        raise ConfigError(
            f"--out {out}: the run's record takes about {describe_bytes(need)}, more than the "
            f"{describe_bytes(free)} free there (--no-mcap writes about a fifth as much on the "
            "testbed; or shorten --duration)"
        )


def _named_comparison(args: argparse.Namespace) -> str | None:
    """`hil run walking`: a named comparison on its robot's built-in configuration; from here on
    the arguments read as the comparison's (no experiment)."""
    if args.experiment not in NAMED_COMPARISONS:
        return None
    named, args.experiment = args.experiment, None
    if args.config is None and args.robot is None:
        args.robot = NAMED_COMPARISONS[named]
    return named


def cmd_run(args: argparse.Namespace) -> int:
    named = _named_comparison(args)
    if args.experiment is not None:
        try:
            get_experiment(args.experiment)
        except ValueError as exc:
            raise ConfigError(f"hil run: {exc}") from None
    config = _configured(args)
    if named is not None and robot_of(config) is not NAMED_COMPARISONS[named]:
        raise ConfigError(f"`hil run {named}` is for the robot {str(NAMED_COMPARISONS[named])!r}")
    faults, overruns = parse_injections(args.inject)
    embedded = (args.config is None or args.emulate) and not (args.attach and args.config is None)
    _check_combinations(args, embedded, faults)
    _check_timeline(args, faults, overruns)
    if args.experiment is not None:
        experiment = get_experiment(args.experiment)
        check_designs(config, [(experiment, _choice(args, config, experiment))], args.duration)
    else:
        check_designs(config, comparison_runs(config, named))
    _check_out(args, config)
    _check_ros2(args)
    setup = Setup.EMBEDDED if embedded else Setup.ATTACHED if args.attach else Setup.HARDWARE
    sinks = _live(args)
    try:
        return _run(args, config, setup, faults, overruns, sinks, named)
    finally:
        for sink in sinks:
            sink.close()


def _run(
    args: argparse.Namespace,
    config: Config,
    setup: Setup,
    faults: tuple,
    overruns: tuple,
    sinks: tuple[MessageSink, ...],
    named: str | None = None,
) -> int:
    session = Session(
        config,
        setup,
        realtime=args.realtime,
        attach=load_attach(args.attach) if args.attach else None,
        overrides=connection_overrides(args),
        seed=args.seed,
        out_root=args.out,
        plots=not args.no_plots,
        json_output=args.json,
        mcap=not args.no_mcap,
        ros2=args.ros2,
        sinks=sinks,
    )
    stop = StopFlag()
    stop.install()
    try:
        if args.experiment is None:
            outcome = run_comparison(
                session,
                faults=faults,
                overruns=overruns,
                current_guard=args.current_guard == "on",
                stop=stop,
                named=named,
                workers=args.workers,
            )
            if outcome.torque_not_off:
                return ExitCode.TORQUE_NOT_OFF
            return ExitCode.OK if outcome.incomplete is None else ExitCode.FAILED
        experiment = get_experiment(args.experiment)
        choice = _choice(args, config, experiment)
        result = session.run_one(
            experiment,
            choice,
            faults=faults,
            overruns=overruns,
            duration_s=args.duration,
            reboot_first=args.reboot_first,
            stop=stop,
        )
        if result.torque_off_failed:
            return ExitCode.TORQUE_NOT_OFF
        return ExitCode.OK if result.ok else ExitCode.FAILED
    except SessionError as exc:
        print(f"hil run: {exc}", file=sys.stderr)
        return ExitCode.FAILED
    except ReferenceOutsideLimits as exc:
        print(f"hil run: {exc}", file=sys.stderr)
        return ExitCode.USAGE
    finally:
        stop.restore()
