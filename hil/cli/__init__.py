"""The `hil` command.

    hil run [EXPERIMENT] [--controller NAME] [--kdist K] [--config FILE] [--emulate]
            [--realtime] [--out DIR] [--json] [--inject FAULT@T[+D]] [--seed N]
            [--workers N] ...
    hil emulate [--config FILE] [--realtime] [--experiment NAME] [--inject FAULT@T[+D]]
    hil scan --port PATH [--baudrate N]
    hil reboot [--config FILE] [--port ...]
    hil bench bus|loop [--json]
    hil monitor [--config FILE | --attach JSON] [--json] [--rate HZ] [--duration S]
    hil calibrate [--config FILE] [--attach JSON] [--seconds S] [--pose [NAME=]RAD] [--write]
    hil identify LOG_DIR... [--json] [--config FILE] [--figure PATH]
    hil compare RUN_DIR RUN_DIR... [--out DIR]   runs of one experiment side by side
    hil twin RUN_DIR... [--out twin.toml]      the emulator fitted to recorded runs
    hil twin --check TWIN RUN_DIR... [--out DIR]   runs replayed on the twin, the residual
    hil sweep SPEC [--address ADDR] [--workers N] [--out DIR] [--list] [--json]
    hil bench bus|loop|soak|sweep [--json]
    hil config                 print the sample configuration file
    hil model [--robot R | --config FILE] [--json]   each joint's static compliance
    hil export ros2 RUN_DIR [--out FILE]   the run as a ROS 2 bag (the `ros2` extra)
    hil render RUN_DIR [--at T ...] [--out PNG] [--video FILE]   the robot drawn (`render`)

Exit status (`ExitCode`): 0 success, 1 the run ended in a safety stop or failed, 2 bad
arguments or bad configuration (nothing was sent to any device), 3 torque could not be turned
off at the end of a run (the actuators may still hold with torque on).

A Ctrl-C at any moment, from the first import on, ends with status 1 and one line
(`hil: interrupted`), never a traceback: this module imports nothing heavy until `main` runs,
inside its guard.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
from typing import TYPE_CHECKING

from hil.cli.exit_codes import ExitCode

if TYPE_CHECKING:
    from hil.cli.parser import build_parser

__all__ = ["ExitCode", "build_parser", "main"]


def __getattr__(name: str) -> object:
    if name == "build_parser":  # imported on first use: the parser imports the whole product
        from hil.cli.parser import build_parser

        return build_parser
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def main(argv: list[str] | None = None) -> int:
    """The `hil` command; argv None: this process's own arguments (the console script)."""
    try:
        return _main(argv)
    except KeyboardInterrupt:  # during the imports, the parsing, or a command's own clean-up
        return _interrupted(process_ends=argv is None)
    except ImportError as exc:
        # a Ctrl-C inside a compiled module's initialisation (MuJoCo's, pinocchio's) reaches
        # Python as "ImportError: initialization failed" raised from the KeyboardInterrupt
        if not _raised_by_an_interrupt(exc):
            raise
        return _interrupted(process_ends=argv is None)


def _raised_by_an_interrupt(exc: BaseException) -> bool:
    seen: set[int] = set()
    cause: BaseException | None = exc
    while cause is not None and id(cause) not in seen:
        if isinstance(cause, KeyboardInterrupt):
            return True
        seen.add(id(cause))
        cause = cause.__cause__ or cause.__context__
    return False


def _interrupted(process_ends: bool) -> int:
    # A second Ctrl-C while this is said, or while the interpreter ends, would print a
    # traceback: ignored from here when this process ends now (not when called from Python).
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    print("hil: interrupted", file=sys.stderr)
    if not process_ends:
        signal.signal(signal.SIGINT, previous)
    return ExitCode.FAILED


def _main(argv: list[str] | None) -> int:
    from hil.cli.parser import build_parser
    from hil.config import ConfigError

    args = build_parser().parse_args(argv)
    try:
        return int(_dispatch(args))
    except ConfigError as exc:
        print(f"hil: configuration error: {exc}", file=sys.stderr)
        return ExitCode.USAGE
    except KeyboardInterrupt:
        raise
    except Exception as exc:  # noqa: BLE001 - no traceback for the user; HIL_DEBUG=1 shows it
        if os.environ.get("HIL_DEBUG"):
            import traceback

            traceback.print_exc()
        print(
            f"hil {args.command}: {type(exc).__name__}: {exc} (set HIL_DEBUG=1 for the traceback)",
            file=sys.stderr,
        )
        return ExitCode.FAILED


def _dispatch(args: argparse.Namespace) -> int:
    if args.command == "config":
        from hil.config import default_config_text
        from hil.vocabulary import Robot

        sys.stdout.write(default_config_text(args.robot or Robot.TESTBED))
        return ExitCode.OK
    if args.command == "model":
        from hil.cli.model import cmd_model

        return cmd_model(args)
    if args.command == "emulate":
        from hil.cli.emulate import cmd_emulate

        return cmd_emulate(args)
    if args.command == "run":
        from hil.cli.run import cmd_run

        return cmd_run(args)
    if args.command in ("scan", "reboot"):
        from hil.cli.devices import cmd_reboot, cmd_scan

        return cmd_scan(args) if args.command == "scan" else cmd_reboot(args)
    if args.command == "monitor":
        from hil.cli.monitor import cmd_monitor

        return cmd_monitor(args)
    if args.command == "calibrate":
        from hil.cli.calibrate import cmd_calibrate

        return cmd_calibrate(args)
    if args.command == "identify":
        from hil.cli.identify import cmd_identify

        return cmd_identify(args)
    if args.command == "twin":
        from hil.cli.twin import cmd_twin

        return cmd_twin(args)
    if args.command == "compare":
        from hil.cli.compare import cmd_compare

        return cmd_compare(args)
    if args.command == "sweep":
        from hil.cli.sweep import cmd_sweep

        return cmd_sweep(args)
    if args.command in ("export", "render"):
        from hil.cli.views import cmd_export, cmd_render

        return cmd_export(args) if args.command == "export" else cmd_render(args)
    if args.command == "bench":
        from hil.cli.bench import cmd_bench

        return cmd_bench(args)
    raise AssertionError(f"unhandled command {args.command}")
