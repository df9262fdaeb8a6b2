"""The commands that show a finished run where robotics engineers look: `hil export ros2
RUN_DIR` (a ROS 2 bag, hil/output/ros2_bag.py) and `hil render RUN_DIR` (snapshots and a
video of the emulated robot, hil/render/)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from hil.cli.exit_codes import ExitCode
from hil.config import ConfigError


def add_view_commands(sub: argparse._SubParsersAction) -> None:
    """`hil export` and `hil render`."""
    add_render_command(sub)
    export = sub.add_parser(
        "export",
        help="write a finished run in another format (ros2: a ROS 2 bag)",
        description="ros2: the run as a ROS 2 bag, one MCAP file in ROS 2's encoding (CDR, "
        "profile ros2) that `ros2 bag info` / `ros2 bag play` and Foxglove read: "
        "/joint_states, /motor_states, the force sensors' wrenches, /tf, /tf_static, "
        "/robot_description, the events and the run's meta and summary. Needs the `ros2` "
        "extra.",
    )
    export.add_argument("format", choices=["ros2"], help="the format (ros2)")
    export.add_argument("run_dir", type=Path, metavar="RUN_DIR", help="a run directory")
    export.add_argument("--out", type=Path, help="the bag's file (default: RUN_DIR/run.ros2.mcap)")


def cmd_export(args: argparse.Namespace) -> int:
    from hil.output.ros2_bag import MISSING_EXTRA
    from hil.output.ros2_export import export_ros2

    run_dir: Path = args.run_dir
    if not (run_dir / "log.csv").is_file():
        raise ConfigError(f"RUN_DIR {run_dir}: no log.csv there (not a run directory)")
    if args.out is not None and args.out.exists():
        raise ConfigError(f"--out {args.out}: exists already (not overwritten)")
    try:
        path = export_ros2(run_dir, args.out)
    except ImportError as exc:
        if str(exc) != MISSING_EXTRA:
            raise
        print(f"hil export: {exc}", file=sys.stderr)
        return ExitCode.USAGE
    print(path)
    return ExitCode.OK


def add_render_command(sub: argparse._SubParsersAction) -> None:
    render = sub.add_parser(
        "render",
        help="draw an emulated run's robot: snapshots at chosen instants and a video",
        description="The robot of a finished run drawn with MuJoCo's offscreen renderer from "
        "the log (link angles; DYROS-JET's pelvis by leg odometry), side view: snapshots at "
        "--at instants in one strip (default: for step-on-object the paper's Fig. 8 "
        "instants, placed at this plan's step onto the box; else five over the run) and, with "
        "--video, the whole run. Needs OpenGL (the `render` extra and Mesa's EGL or OSMesa).",
    )
    render.add_argument("run_dir", type=Path, metavar="RUN_DIR", help="a run directory")
    render.add_argument(
        "--at", type=float, nargs="+", metavar="T", help="run times of the snapshots [s]"
    )
    render.add_argument("--out", type=Path, help="the strip's PNG (default: RUN_DIR/render.png)")
    render.add_argument("--video", type=Path, help="also a video of the run (.mp4 or .gif)")


def cmd_render(args: argparse.Namespace) -> int:
    from hil.output.rundir import load_run
    from hil.render.process import GlUnavailable, render_run_dir

    run_dir: Path = args.run_dir
    if not (run_dir / "log.csv").is_file():
        raise ConfigError(f"RUN_DIR {run_dir}: no log.csv there (not a run directory)")
    run = load_run(run_dir)
    end = float(run.time_s[-1])
    outside = [t for t in args.at or () if not 0.0 <= t <= end]
    if outside:
        raise ConfigError(f"--at {outside}: outside the run (0 to {end:g} s)")
    if args.video is not None and args.video.suffix.lower() not in (".mp4", ".gif"):
        raise ConfigError(f"--video {args.video}: name an .mp4 or a .gif")
    try:
        written = render_run_dir(run_dir, args.at, args.out or run_dir / "render.png", args.video)
    except GlUnavailable as exc:
        print(f"hil render: {exc}", file=sys.stderr)
        return ExitCode.USAGE
    for path in written:
        print(path)
    return ExitCode.OK
