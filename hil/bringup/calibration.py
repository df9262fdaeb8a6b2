"""`hil calibrate`: the zero offsets of every joint, measured at the reference pose.

The configuration's convention (drivers and emulator alike): a device reading r gives the
joint angle q = d (r - o), with d = motor_direction / encoder_direction and o =
motor_offset_rad / encoder_offset_rad. Held at a pose q* (default 0: the link horizontal, the
pose the configuration's offsets are defined at), a reading r* gives the offset o = r* - d q*.
The bus reports q with the configured (d, o_cfg), so r* = o_cfg + d q and

    o_new = o_cfg + d (mean(q) - q*)                                              (1)

averaged over the stated window; the spread (standard deviation and peak-to-peak) of q is
reported with it. The motor offset is the reading with the gear unloaded: hold the link at the
pose (or rest it on a stop at a known angle) so that the spring carries no torque - a link that
hangs on the spring deflects it by m g r / K (3.1 mrad on the paper's testbed).

Direction agreement: with the link still, nothing tells the two encoders' senses apart. If the
joint moves during the window (someone moves it by hand, torque off), the link and motor
increments are compared: their least-squares slope is +1 when the senses agree and -1 when one
of motor_direction / encoder_direction is wrong (trusted only when the two are correlated, |r|
at least DIRECTION_MIN_CORRELATION). Which one (against the joint's positive sense)
only a person can tell: move the joint by hand in its positive direction while `hil monitor`
runs; both angles must increase. A joint that moved is not at rest: its offsets are not given.

Nothing is written to any actuator (the bus is opened read-only).
"""

from __future__ import annotations

import enum
import math
import re
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from drivers.joint_bus import JointBus
from hil.config import Config, ConfigError, parse_config

AT_REST_PEAK_TO_PEAK_RAD = 1e-3  # more motion than this in the window: not at rest
DIRECTION_MIN_MOTION_RAD = 0.02  # less motion than this: the direction check cannot tell
DIRECTION_MIN_CORRELATION = 0.9  # |correlation| below this: the two do not move together
OFFSET_KEYS = ("motor_offset_rad", "encoder_offset_rad")


class DirectionCheck(enum.StrEnum):
    AGREE = "agree"
    DISAGREE = "disagree"  # one of motor_direction / encoder_direction is wrong
    NOT_MOVED = "not moved"  # the joint did not move enough to tell
    INCONCLUSIVE = "inconclusive"  # it moved, but the two angles did not move together


@dataclass(frozen=True)
class JointCalibration:
    """One joint's measurement (angles in the joint frame of the configured offsets)."""

    name: str
    samples: int
    pose_rad: float
    motor_mean_rad: float
    motor_std_rad: float
    motor_peak_to_peak_rad: float
    link_mean_rad: float
    link_std_rad: float
    link_peak_to_peak_rad: float
    configured_motor_offset_rad: float
    configured_encoder_offset_rad: float
    motor_offset_rad: float  # (1)
    encoder_offset_rad: float  # (1)
    direction: DirectionCheck
    slope: float  # link increments over motor increments (NaN when not moved)

    @property
    def at_rest(self) -> bool:
        return max(self.motor_peak_to_peak_rad, self.link_peak_to_peak_rad) <= (
            AT_REST_PEAK_TO_PEAK_RAD
        )

    @property
    def offsets(self) -> dict[str, float]:
        return {
            "motor_offset_rad": self.motor_offset_rad,
            "encoder_offset_rad": self.encoder_offset_rad,
        }


@dataclass(frozen=True)
class Calibration:
    joints: tuple[JointCalibration, ...]
    seconds: float
    rate_hz: float

    @property
    def at_rest(self) -> bool:
        return all(joint.at_rest for joint in self.joints)


def direction_check(motor_rad: np.ndarray, link_rad: np.ndarray) -> tuple[DirectionCheck, float]:
    """Agreement of the two senses from a joint's motion (see the module docstring)."""
    finite = np.isfinite(motor_rad) & np.isfinite(link_rad)
    motor, link = motor_rad[finite], link_rad[finite]
    if motor.size < 3 or np.ptp(motor) < DIRECTION_MIN_MOTION_RAD:
        return DirectionCheck.NOT_MOVED, math.nan
    dm, dl = motor - motor.mean(), link - link.mean()
    covariance = float(dm @ dl)
    slope = covariance / float(dm @ dm)
    if abs(covariance) < DIRECTION_MIN_CORRELATION * math.sqrt(float(dm @ dm) * float(dl @ dl)):
        return DirectionCheck.INCONCLUSIVE, slope
    return (DirectionCheck.AGREE if slope > 0 else DirectionCheck.DISAGREE), slope


def joint_calibration(
    config: Config, index: int, motor_rad: np.ndarray, link_rad: np.ndarray, pose_rad: float
) -> JointCalibration:
    """(1) for one joint from its readings over the window (NaN: a reading that failed)."""
    joint = config.joints[index]
    motor, link = motor_rad[np.isfinite(motor_rad)], link_rad[np.isfinite(link_rad)]
    if motor.size == 0 or link.size == 0:
        raise ConfigError(f"joint {joint.name}: no valid reading in the calibration window")
    direction, slope = direction_check(motor_rad, link_rad)
    motor_mean, link_mean = float(motor.mean()), float(link.mean())
    return JointCalibration(
        name=joint.name,
        samples=int(min(motor.size, link.size)),
        pose_rad=pose_rad,
        motor_mean_rad=motor_mean,
        motor_std_rad=float(motor.std()),
        motor_peak_to_peak_rad=float(np.ptp(motor)),
        link_mean_rad=link_mean,
        link_std_rad=float(link.std()),
        link_peak_to_peak_rad=float(np.ptp(link)),
        configured_motor_offset_rad=joint.motor_offset_rad,
        configured_encoder_offset_rad=joint.encoder_offset_rad,
        motor_offset_rad=joint.motor_offset_rad + joint.motor_direction * (motor_mean - pose_rad),
        encoder_offset_rad=joint.encoder_offset_rad
        + joint.encoder_direction * (link_mean - pose_rad),
        direction=direction,
        slope=slope,
    )


def calibrate(
    config: Config,
    bus: JointBus,
    *,
    seconds: float,
    poses_rad: Mapping[str, float] | None = None,
    stopped: Callable[[], bool] = lambda: False,
    clock: Callable[[], float] = time.monotonic,
    sleep: Callable[[float], None] = time.sleep,
) -> Calibration:
    """Read `bus` (open, read-only) at the loop rate for `seconds`, then (1) per joint."""
    rate_hz = config.loop.rate_hz
    count = max(3, round(seconds * rate_hz))
    n = len(config.joints)
    motor = np.full((count, n), math.nan)
    link = np.full((count, n), math.nan)
    start = clock()
    taken = 0
    for k in range(count):
        if stopped():
            break
        sample = bus.read()
        motor[k] = np.where(sample.motor_valid, sample.motor_angle_rad, math.nan)
        link[k] = np.where(sample.link_valid, sample.link_angle_rad, math.nan)
        taken = k + 1
        wait = start + taken / rate_hz - clock()
        if wait > 0:
            sleep(wait)
    poses = dict(poses_rad or {})
    unknown = sorted(set(poses) - set(config.joint_names))
    if unknown:
        raise ConfigError(f"--pose names joints that do not exist: {unknown}")
    joints = tuple(
        joint_calibration(config, i, motor[:taken, i], link[:taken, i], poses.get(j.name, 0.0))
        for i, j in enumerate(config.joints)
    )
    return Calibration(joints, taken / rate_hz, rate_hz)


def _number(value: float) -> str:
    return f"{value:.9f}"


def calibration_fragment(calibration: Calibration) -> str:
    """The [[joint]] keys to paste into the configuration file, with the spread as comments."""
    lines = [
        f"# hil calibrate: {calibration.joints[0].samples if calibration.joints else 0} samples "
        f"over {calibration.seconds:.2f} s at {calibration.rate_hz:g} Hz, joint frame of the "
        "configured offsets; std / peak-to-peak of the readings"
    ]
    for joint in calibration.joints:
        lines += [
            "[[joint]]",
            f'name = "{joint.name}"',
            f"motor_offset_rad = {_number(joint.motor_offset_rad)}    # pose {joint.pose_rad:g} "
            f"rad; motor std {joint.motor_std_rad:.2e}, p-p {joint.motor_peak_to_peak_rad:.2e}",
            f"encoder_offset_rad = {_number(joint.encoder_offset_rad)}  # link std "
            f"{joint.link_std_rad:.2e}, p-p {joint.link_peak_to_peak_rad:.2e}; directions: "
            f"{joint.direction}",
        ]
    return "\n".join(lines) + "\n"


_TABLE_HEADER = re.compile(r"^\s*\[")
_JOINT_HEADER = re.compile(r"^\s*\[\[\s*joint\s*\]\]\s*(#.*)?$")
_NAME = re.compile(r"""^\s*name\s*=\s*(["'])(?P<name>.*?)\1""")


def _key_line(key: str) -> re.Pattern[str]:
    return re.compile(rf"^(?P<head>\s*{key}\s*=\s*)(?P<value>[^#\n]*?)(?P<tail>\s*(#.*)?)$")


def update_config_text(text: str, offsets: Mapping[str, Mapping[str, float]]) -> str:
    """The configuration text with these keys of these [[joint]] tables changed and nothing
    else: comments, order and layout are kept (the text is edited, not re-serialised). A key the
    table does not have is added after its `name` line. `offsets`: {joint name: {key: value}}.
    The result is parsed and checked to hold exactly the new values."""
    lines = text.splitlines(keepends=True)
    tables = _joint_tables(lines)
    missing = sorted(set(offsets) - set(tables))
    if missing:
        raise ConfigError(f"the configuration file has no [[joint]] named {missing}")
    # Work from the last table up, so that inserted lines do not shift the ones still to do.
    for name in sorted(offsets, key=lambda n: tables[n][0], reverse=True):
        start, end, name_line = tables[name]
        for key, value in offsets[name].items():
            pattern = _key_line(key)
            for i in range(start, end):
                match = pattern.match(lines[i].rstrip("\n"))
                if match:
                    newline = "\n" if lines[i].endswith("\n") else ""
                    lines[i] = f"{match['head']}{_number(value)}{match['tail']}{newline}"
                    break
            else:
                indent = re.match(r"^\s*", lines[name_line]).group(0)  # type: ignore[union-attr]
                lines.insert(name_line + 1, f"{indent}{key} = {_number(value)}\n")
                end += 1
    result = "".join(lines)
    _check_updated(result, offsets)
    return result


def _joint_tables(lines: list[str]) -> dict[str, tuple[int, int, int]]:
    """{name: (first line, end line, line of `name = ...`)} of every [[joint]] table."""
    tables: dict[str, tuple[int, int, int]] = {}
    i = 0
    while i < len(lines):
        if not _JOINT_HEADER.match(lines[i]):
            i += 1
            continue
        start = i + 1
        end = start
        while end < len(lines) and not _TABLE_HEADER.match(lines[end]):
            end += 1
        for k in range(start, end):
            match = _NAME.match(lines[k])
            if match:
                tables[match["name"]] = (start, end, k)
                break
        i = end
    return tables


def _check_updated(text: str, offsets: Mapping[str, Mapping[str, float]]) -> None:
    config = parse_config(text, source="<updated configuration>")
    for joint in config.joints:
        for key, value in offsets.get(joint.name, {}).items():
            if not math.isclose(getattr(joint, key), float(_number(value)), abs_tol=1e-12):
                raise ConfigError(f"updating {joint.name} {key} failed: the file reads otherwise")
