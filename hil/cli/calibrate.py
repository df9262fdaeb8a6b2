"""`hil calibrate`: zero offsets at the reference pose (see hil/bringup/calibration.py)."""

from __future__ import annotations

import argparse
import math
import os
import shutil
import sys
import tempfile
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

# --seconds: the averaging window, at most 10 minutes (120,000 readings at 200 Hz, held in
# memory; the offsets are measured at rest, which a longer window does not make truer)
MAX_SECONDS = 600.0


def parse_poses(texts: list[str], config: Config) -> dict[str, float]:
    """--pose RAD (every joint) or --pose NAME=RAD, repeatable; each within its joint's
    [min_angle_rad, max_angle_rad] (the robot is held there)."""
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
            section = config.joints[config.joint_names.index(joint)]
            if not section.min_angle_rad <= angle <= section.max_angle_rad:
                raise ConfigError(
                    f"--pose {text!r}: {angle:g} rad is outside joint {joint!r}'s range "
                    f"[{section.min_angle_rad:g}, {section.max_angle_rad:g}] rad"
                )
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
    """Update the file in place, the old one kept as a backup; returns the backup's path."""
    text = path.read_text()
    updated = update_config_text(text, {j.name: j.offsets for j in calibration.joints})
    return write_keeping_backup(path, updated)


def write_keeping_backup(path: Path, text: str) -> Path:
    """`path` replaced by `text` in one rename, the old file kept as PATH.bak (PATH.bak-2, ...
    when one exists); returns the backup's path. A symbolic link is followed: the file it names
    is the one replaced (and backed up beside it), the link stays. The new text goes to a
    temporary file beside it first (written and synced); if anything fails, the temporary and
    the new backup are removed and the error raised: nothing is left behind, the file is as it
    was."""
    path = Path(os.path.realpath(path))
    old = path.read_bytes()
    backup: Path | None = None
    fd, name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    tmp = Path(name)
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        shutil.copymode(path, tmp)
        backup = _new_backup(path, old)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        if backup is not None:
            backup.unlink(missing_ok=True)
        raise
    return backup


def _new_backup(path: Path, data: bytes) -> Path:
    """PATH.bak, or PATH.bak-2, ...: created exclusively, holding `data`."""
    number = 1
    while True:
        candidate = path.with_name(path.name + ".bak" + (f"-{number}" if number > 1 else ""))
        try:
            with open(candidate, "xb") as f:
                f.write(data)
        except FileExistsError:
            number += 1
            continue
        except BaseException:
            candidate.unlink(missing_ok=True)
            raise
        shutil.copystat(path, candidate)
        return candidate


def _check_writable(path: Path) -> None:
    """--write: the file must be there and its directory writable (a temporary file and the
    backup go beside it), judged before anything is read."""
    if not path.is_file():
        raise ConfigError(f"--write {path}: no such file")
    target = Path(os.path.realpath(path))  # a link's file is the one written
    try:
        fd, name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".check", dir=target.parent)
        os.close(fd)
        os.unlink(name)
    except OSError as exc:
        raise ConfigError(f"--write {path}: cannot write beside it: {exc}") from None


def cmd_calibrate(args: argparse.Namespace) -> int:
    if not (math.isfinite(args.seconds) and 0 < args.seconds <= MAX_SECONDS):
        raise ConfigError(
            f"--seconds: must be a time in (0, {MAX_SECONDS:g}] s, got {args.seconds}"
        )
    if args.write and args.config is None:
        raise ConfigError("--write updates the configuration file: give it with --config FILE")
    if args.write:
        _check_writable(args.config)
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
        try:
            backup = _write(args.config, calibration)
        except OSError as exc:
            print(
                f"hil calibrate: cannot write {args.config}: {exc}; it is unchanged",
                file=sys.stderr,
            )
            return ExitCode.FAILED
        target = Path(os.path.realpath(args.config))
        written = f"{args.config}" + (f" (-> {target})" if target != args.config.absolute() else "")
        print(f"hil calibrate: updated {written} (the old file: {backup})", file=sys.stderr)
    return ExitCode.OK
