"""`hil calibrate`: zero offsets at the reference pose (see hil/bringup/calibration.py)."""

from __future__ import annotations

import argparse
import math
import shutil
import sys
from pathlib import Path

from drivers.joint_bus import BusError
from hil.bringup import (
    Calibration,
    DirectionCheck,
    JointCalibration,
    calibrate,
    calibration_fragment,
)
from hil.bringup.calibration import AT_REST_PEAK_TO_PEAK_RAD, update_config_text
from hil.cli.common import checked_config
from hil.cli.exit_codes import ExitCode
from hil.cli.monitor import read_only_bus
from hil.config import Config, ConfigError
from hil.loop import StopFlag
from hil.output.rundir import unique_dir


def parse_poses(texts: list[str], config: Config) -> dict[str, float]:
    """--pose RAD (every joint) or --pose NAME=RAD, repeatable."""
    poses: dict[str, float] = {}
    for text in texts:
        name, sep, value = text.rpartition("=")
        try:
            angle = float(value)
        except ValueError:
            raise ConfigError(f"--pose {text!r}: expected RAD or NAME=RAD") from None
        if not math.isfinite(angle):
            raise ConfigError(f"--pose {text!r}: the angle must be finite")
        for joint in [name] if sep else config.joint_names:
            if joint not in config.joint_names:
                raise ConfigError(f"--pose {text!r}: no joint {joint!r} ({config.joint_names})")
            poses[joint] = angle
    return poses


def _report(calibration: Calibration, config: Config) -> str:
    margin = config.safety.zero_offset_margin_rad
    lines = []
    for joint in calibration.joints:
        gap = joint.link_mean_rad - joint.motor_mean_rad
        verdict = "within" if abs(gap) <= margin else "OUTSIDE"
        lines.append(
            f"{joint.name}: motor {joint.motor_mean_rad:+.6f} rad (std {joint.motor_std_rad:.1e}), "
            f"link {joint.link_mean_rad:+.6f} rad (std {joint.link_std_rad:.1e}) with the "
            f"configured offsets: they disagree by {gap:+.6f} rad, {verdict} "
            f"zero_offset_margin_rad = {margin}"
        )
        if not joint.at_rest:
            lines.append(
                f"  moved during the window (peak-to-peak motor "
                f"{joint.motor_peak_to_peak_rad:.2e}, link {joint.link_peak_to_peak_rad:.2e} rad "
                f"> {AT_REST_PEAK_TO_PEAK_RAD}): no offsets; hold it still at the pose"
            )
        lines.append(f"  directions of motor and link encoder: {_direction_text(joint)}")
    return "\n".join(lines)


def _direction_text(joint: JointCalibration) -> str:
    if joint.direction is DirectionCheck.AGREE:
        return f"agree (link/motor slope {joint.slope:+.3f} while it moved)"
    if joint.direction is DirectionCheck.DISAGREE:
        return (
            f"DISAGREE (slope {joint.slope:+.3f}): flip motor_direction or encoder_direction - "
            "the one whose angle falls when the joint moves in its positive sense"
        )
    if joint.direction is DirectionCheck.INCONCLUSIVE:
        return f"inconclusive (slope {joint.slope:+.3f}: the two did not move together)"
    return (
        "not checked (the joint did not move): with torque off, move it by hand during "
        "`hil calibrate` or watch `hil monitor` - both angles must rise in its positive sense"
    )


def _write(path: Path, calibration: Calibration) -> Path:
    """Update the file in place after copying it to a backup; returns the backup's path."""
    text = path.read_text()
    updated = update_config_text(text, {j.name: j.offsets for j in calibration.joints})
    backup = unique_dir(path.with_name(path.name + ".bak"))
    shutil.copy2(path, backup)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(updated)
    tmp.replace(path)
    return backup


def cmd_calibrate(args: argparse.Namespace) -> int:
    if not (math.isfinite(args.seconds) and args.seconds > 0):
        raise ConfigError(f"--seconds: must be a finite time > 0 s, got {args.seconds}")
    if args.write and args.config is None:
        raise ConfigError("--write updates the configuration file: give it with --config FILE")
    config = checked_config(args.config)
    poses = parse_poses(args.pose, config)
    stop = StopFlag()
    stop.install()
    try:
        with read_only_bus(args, config) as bus:
            print(
                f"hil calibrate: averaging {args.seconds:g} s of readings, read-only; hold every "
                "joint still at its reference pose (gear unloaded)",
                file=sys.stderr,
            )
            calibration = calibrate(
                config,
                bus,
                seconds=args.seconds,
                poses_rad=poses,
                stopped=lambda: stop.reason is not None,
            )
    except BusError as exc:
        print(f"hil calibrate: {exc}", file=sys.stderr)
        return ExitCode.FAILED
    finally:
        stop.restore()
    if stop.reason is not None:
        print("hil calibrate: interrupted; nothing written", file=sys.stderr)
        return ExitCode.FAILED
    print(_report(calibration, config), file=sys.stderr)
    if not calibration.at_rest:
        return ExitCode.FAILED
    sys.stdout.write(calibration_fragment(calibration))
    if args.write:
        backup = _write(args.config, calibration)
        print(f"hil calibrate: updated {args.config} (the old file: {backup})", file=sys.stderr)
    return ExitCode.OK
