"""The `hil` command line: one parser, one sub-parser per command."""

from __future__ import annotations

import argparse
from pathlib import Path

import hil
from controller import COMPOSITION_READINGS, CONTROLLER_NAMES, GC_COMPLIANCES
from hil.cli.twin import add_twin
from hil.cli.views import add_view_commands
from hil.robots import EXPERIMENTS, NAMED_COMPARISONS, PROFILES

BENCH_TARGETS = ("bus", "loop", "pacing", "soak", "log", "sweep")


def attach_text(text: str) -> str:
    """--attach: refused at once when it names nothing (an empty --attach would otherwise
    read as no --attach: the configuration's hardware ports, or the embedded emulator)."""
    if not text.strip():
        raise argparse.ArgumentTypeError(
            "names nothing: give the JSON line `hil emulate` printed, or a file holding it"
        )
    return text


def _add_connection_overrides(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("connection overrides (point a config at other ports)")
    group.add_argument("--port", help="Dynamixel serial port (overrides [[dynamixel]] port)")
    group.add_argument("--baudrate", type=int, help="Dynamixel baud (overrides the config)")
    group.add_argument("--can-interface", help="python-can interface, e.g. socketcan, slcan")
    group.add_argument("--can-channel", help="python-can channel, e.g. can0 or /dev/pts/4")
    group.add_argument(
        "--attach",
        type=attach_text,
        metavar="JSON",
        help="the first line `hil emulate` printed (or a file holding it): use its ports",
    )


def _add_robot(parser: argparse.ArgumentParser) -> None:
    robots = "; ".join(f"{robot}: {each.summary}" for robot, each in PROFILES.items())
    parser.add_argument(
        "--robot",
        choices=sorted(str(robot) for robot in PROFILES),
        help="the robot whose built-in configuration to use (default: the experiment's robot; "
        f"testbed otherwise). {robots}",
    )


def _add_run(sub: argparse._SubParsersAction) -> None:
    run = sub.add_parser(
        "run",
        help="run an experiment (or, without one, the paper's whole testbed comparison)",
        description="Without --config: on the embedded emulated testbed, in lock-step. With "
        "--config FILE: on the hardware FILE describes (add --emulate to emulate it instead).",
    )
    run.add_argument(
        "experiment",
        nargs="?",
        metavar="EXPERIMENT",
        help="the experiment to run: one of "
        + ", ".join(sorted([*EXPERIMENTS, *NAMED_COMPARISONS]))
        + ", or your own as path/to/file.py:Name (hil/experiments/base.py); omit for the "
        "robot's comparison; "
        + "; ".join(
            f"`{name}`: a comparison on {robot}" for name, robot in NAMED_COMPARISONS.items()
        ),
    )
    run.add_argument(
        "--controller",
        default=None,
        metavar="NAME|FILE.py:CLASS|MODULE:CLASS",
        help=f"one of {', '.join(CONTROLLER_NAMES)} (or an installed package's), or your own: "
        "path/to/file.py:Class or package.module:Class (hil/controllers/contract.py; its "
        "parameters from [controller.params]); default: the config's [controller] name",
    )
    run.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a parameter of a plug-in controller, as in [controller.params] (VALUE in TOML: "
        '0.5, true, "text"); repeat for more',
    )
    run.add_argument("--kdist", type=float, help="DOB gain Kdist (default: the config's)")
    run.add_argument(
        "--composition",
        choices=list(COMPOSITION_READINGS),
        help="reading of the paper's (25) (default: the config's; see controller/composition.py)",
    )
    run.add_argument(
        "--gc-compliance",
        choices=list(GC_COMPLIANCES),
        help="what the gravity compensator (8) offsets: the whole joint's compliance 1/K + "
        "1/(Kpp kv), or the gear's K^-1 as the paper writes it (default: the config's)",
    )
    run.add_argument(
        "--config", type=Path, help="configuration file (default: the built-in one of --robot)"
    )
    _add_robot(run)
    run.add_argument("--emulate", action="store_true", help="emulate the --config hardware")
    run.add_argument("--realtime", action="store_true", help="pace with the wall clock")
    run.add_argument("--out", type=Path, default=Path("runs"), help="output directory root")
    run.add_argument("--json", action="store_true", help="last stdout line: metrics as JSON")
    run.add_argument(
        "--inject",
        action="append",
        default=[],
        metavar="FAULT@T[+D]",
        help="inject a fault at T s for D s (emulator faults: dropped_reply, corrupt_crc, "
        "silent_id, dead_encoder, stale_encoder, noisy_encoder; loop fault: overrun)",
    )
    run.add_argument("--seed", type=int, help="emulator seed (default: the config's)")
    run.add_argument("--duration", type=float, help="override the experiment's duration [s]")
    run.add_argument(
        "--reboot-first",
        action="store_true",
        help="reboot actuators that report a hardware error, then home slowly, then run",
    )
    _add_run_output(run)
    run.add_argument(
        "--current-guard",
        choices=["on", "off"],
        help="the software overload guard (default: the config's; the comparison runs without "
        "it, as the paper did, so the actuator's own protection is what acts)",
    )
    _add_connection_overrides(run)


def _add_run_output(run: argparse.ArgumentParser) -> None:
    """What `hil run` writes and shows, and how many runs of a comparison go at a time."""
    run.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    run.add_argument(
        "--no-mcap", action="store_true", help="do not write run.mcap beside the CSV log"
    )
    run.add_argument(
        "--ros2",
        action="store_true",
        help="also write the run as a ROS 2 bag, run.ros2.mcap (the `ros2` extra; "
        "`hil export ros2 RUN_DIR` makes one after the run)",
    )
    run.add_argument(
        "--live",
        action="store_true",
        help="serve the run's signals to Foxglove (WebSocket) while it goes",
    )
    run.add_argument(
        "--live-host",
        default="127.0.0.1",
        help="address the live server listens on (default: loopback only)",
    )
    run.add_argument("--live-port", type=int, default=8765, help="its port (8765; 0: any free)")
    run.add_argument(
        "--workers",
        type=int,
        metavar="N",
        help="the comparison's runs N at a time, each in its own process with its own emulator "
        "(default and at most: one per CPU this process may use, os.sched_getaffinity; "
        "1: one after the other, in this process)",
    )


def _add_identify(sub: argparse._SubParsersAction) -> None:
    identify = sub.add_parser(
        "identify",
        help="fit the joint's constants (K, D, Kp, the servo's gains) from `hil run identify` runs",
        description="Fit gear stiffness and damping, the paper's first-order servo gain Kp (4) "
        "and the actuator's cascade (position gain, velocity gain and integral time) to the "
        "logs of identification runs (`hil run identify`), with 95 % intervals; print a "
        "configuration fragment and write a fit-quality figure next to the first log.",
    )
    identify.add_argument("logs", nargs="+", type=Path, metavar="LOG_DIR", help="run directory")
    identify.add_argument("--json", action="store_true", help="last stdout line: JSON result")
    identify.add_argument(
        "--config",
        type=Path,
        help="the configuration whose [model] link inertia and gravity moment the fit is told "
        "(default: the one the run recorded)",
    )
    identify.add_argument(
        "--figure", type=Path, help="the figure file (default: LOG_DIR/identification.png)"
    )


def _add_compare(sub: argparse._SubParsersAction) -> None:
    compare = sub.add_parser(
        "compare",
        help="overlay runs of one experiment and put their metrics side by side",
        description="Any two or more run directories of one experiment (any controller, any "
        "configuration): their figures overlaid, their metrics and endings in one table, and "
        "report.md with the figures in --out. Reads the directories only.",
    )
    compare.add_argument("runs", nargs="+", type=Path, metavar="RUN_DIR", help="run directories")
    compare.add_argument(
        "--out", type=Path, help="where report.md and the figures go (default: a new "
        "runs/TIMESTAMP-compare-EXPERIMENT)",
    )  # fmt: skip


def _add_sweep(sub: argparse._SubParsersAction) -> None:
    sweep = sub.add_parser(
        "sweep",
        help="run an experiment over a grid or Monte Carlo sample of parameters, on Ray",
        description="Runs every (point, experiment, controller) of SPEC on Ray (this machine by "
        "default, a cluster with --address), each through the same code as `hil run`; writes "
        "results.csv, relations.csv, maps/*.png and summary.json to --out (default "
        "runs/sweep-SPEC); rerunning the same command resumes.",
    )
    sweep.add_argument("spec", nargs="?", help="a TOML file, or a shipped spec's name (--list)")
    sweep.add_argument("--list", action="store_true", help="name the shipped specs")
    sweep.add_argument("--address", help="join the Ray cluster at this address")
    sweep.add_argument("--workers", type=int, help="CPUs of the local Ray (default: all)")
    sweep.add_argument("--out", type=Path, help="output directory (default runs/sweep-SPEC)")
    sweep.add_argument("--config", type=Path, help="base configuration (default: built-in)")
    sweep.add_argument("--max-runs", type=int, help="run at most N pending runs, then stop")
    sweep.add_argument("--json", action="store_true", help="last stdout line: summary JSON")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="hil",
        description="Kim et al. (ICRA 2018) GC + DOB + LQR on flexible-joint Dynamixel Pro "
        "actuators: the real testbed, or its byte-exact emulation.",
    )
    parser.add_argument("--version", action="version", version=f"hil {hil.__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    _add_run(sub)

    emulate = sub.add_parser("emulate", help="serve the virtual testbed until interrupted")
    emulate.add_argument("--config", type=Path, help="hardware to emulate (default: built-in)")
    _add_robot(emulate)
    emulate.add_argument("--realtime", action="store_true", help="wall-clock physics and wire time")
    emulate.add_argument(
        "--experiment",
        choices=sorted(EXPERIMENTS),
        help="build this experiment's world (block, pushes)",
    )
    emulate.add_argument("--inject", action="append", default=[], metavar="FAULT@T[+D]")
    emulate.add_argument("--seed", type=int)
    emulate.add_argument("--spec-file", type=Path, help=argparse.SUPPRESS)

    scan = sub.add_parser("scan", help="list the Dynamixel IDs and models on a port")
    scan.add_argument("--port", required=True)
    scan.add_argument("--baudrate", type=int, default=None, help="default: try the usual bauds")
    scan.add_argument("--json", action="store_true")

    reboot = sub.add_parser(
        "reboot", help="reboot the actuators (clears latched hardware errors), torque stays off"
    )
    reboot.add_argument("--config", type=Path)
    reboot.add_argument("--json", action="store_true")
    _add_connection_overrides(reboot)

    bench = sub.add_parser("bench", help="measure the bus or the loop and print figures")
    bench.add_argument("what", choices=BENCH_TARGETS)
    bench.add_argument("--json", action="store_true")
    bench.add_argument(
        "--cycles", type=int, default=None, help="cycles per measurement (soak: ticks in all)"
    )
    bench.add_argument("--seed", type=int, default=0, help="soak: the faults' random seed")
    bench.add_argument("--config", type=Path, help="hardware to emulate (default: built-in)")
    _add_robot(bench)
    bench.add_argument(
        "--runs", type=int, default=None, help="sweep: runs per measurement; pacing: pairs of runs"
    )

    _add_identify(sub)
    _add_compare(sub)
    add_twin(sub)  # hil twin (hil/cli/twin.py)
    _add_sweep(sub)
    add_view_commands(sub)  # hil export, hil render

    _add_bringup(sub)
    config = sub.add_parser("config", help="print a built-in configuration file (a template)")
    _add_robot(config)

    model = sub.add_parser(
        "model",
        help="each joint's static compliance: the controller's model and the emulated robot",
        description="Per joint: the gear stiffness K, the position servo's cascade (Kpp, kv, "
        "Ti) and its static stiffness Kpp kv, the joint's compliance 1/K + 1/(Kpp kv) and the "
        "gear's 1/K (the gravity compensator's two readings, [controller] gc_compliance), as "
        "the configuration's [model] has them and as the emulator builds the robot. Reads "
        "nothing from any device.",
    )
    model.add_argument("--config", type=Path, help="configuration file (default: built-in)")
    _add_robot(model)
    model.add_argument("--json", action="store_true", help="one JSON line instead of the table")
    return parser


def _add_bringup(sub: argparse._SubParsersAction) -> None:
    monitor = sub.add_parser(
        "monitor",
        help="a live table of every joint, read-only (torque is left as found)",
        description="Reads every joint at a steady rate and flags what is outside the "
        "configuration's limits. Nothing is written to any actuator; Ctrl-C leaves everything "
        "as it was.",
    )
    monitor.add_argument("--config", type=Path, help="configuration file (default: built-in)")
    monitor.add_argument("--json", action="store_true", help="one JSON object per sample line")
    monitor.add_argument("--rate", type=float, default=10.0, help="samples per second (10)")
    monitor.add_argument("--duration", type=float, help="stop after this many seconds")
    _add_connection_overrides(monitor)

    calibrate = sub.add_parser(
        "calibrate",
        help="measure the zero offsets at the reference pose (read-only)",
        description="Hold every joint still at its reference pose (torque off, gear unloaded); "
        "prints motor_offset_rad and encoder_offset_rad per joint, or with --write updates "
        "the --config file in place (a backup is kept).",
    )
    calibrate.add_argument("--config", type=Path, help="configuration file (default: built-in)")
    calibrate.add_argument("--seconds", type=float, default=2.0, help="averaging window [s] (2)")
    calibrate.add_argument(
        "--pose",
        action="append",
        default=[],
        metavar="[NAME=]RAD",
        help="the joint angle the robot is held at (default 0 for every joint)",
    )
    calibrate.add_argument(
        "--write", action="store_true", help="update the --config file (keeps FILE.bak)"
    )
    _add_connection_overrides(calibrate)
