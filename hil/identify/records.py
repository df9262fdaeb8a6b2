"""What the fit reads: one joint's measured signals from a run, and the figures it must be told.

A run log (hil/output/runlog.py) has, per joint, goal_rad, motor_angle_rad, link_angle_rad,
motor_velocity_rad_s, motor_current_a and torque_enabled at the loop rate, plus time_s. Row k
holds the measurements sampled at t_k and the goal written after them, which the actuator
follows over [t_k, t_k+1). A row whose goal is not a number sent nothing (the actuator keeps
the previous goal).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

# ROBOTIS e-Manual, H54-200-S500-R specifications: continuous torque 44.7 N m at 9.3 A. An
# estimate of the output torque per ampere: the absolute scale of the velocity-loop gain rests
# on it (see the package docstring).
H54_TORQUE_CONSTANT_NM_PER_A = 44.7 / 9.3
STANDARD_GRAVITY_M_S2 = 9.81

# The smallest log the fit accepts: 5 s at 200 Hz. Shorter runs cannot show the servo's
# integral action and barely the low end of the servo's bandwidth.
MIN_SAMPLES = 1000

SIGNAL_COLUMNS = (
    "goal_rad",
    "motor_angle_rad",
    "link_angle_rad",
    "motor_velocity_rad_s",
    "motor_current_a",
)


class LogFormatError(ValueError):
    """The log lacks a column the fit needs, or has no usable stretch of samples."""


@dataclass(frozen=True)
class JointLog:
    """One joint's signals over an uninterrupted stretch of a run, uniformly sampled (SI).

    goal_rad[k] is the goal held over [time_s[k], time_s[k+1]); the others are sampled at
    time_s[k]. `source` names where it came from (for messages).
    """

    time_s: np.ndarray
    goal_rad: np.ndarray
    motor_angle_rad: np.ndarray
    link_angle_rad: np.ndarray
    motor_velocity_rad_s: np.ndarray
    motor_current_a: np.ndarray
    source: str = "log"

    def __post_init__(self) -> None:
        n = len(self.time_s)
        for name in ("time_s", *SIGNAL_COLUMNS):
            array = np.array(getattr(self, name), dtype=float)
            if array.shape != (n,):
                raise LogFormatError(f"{self.source}: {name} must be 1-D of length {n}")
            if not np.all(np.isfinite(array)):
                raise LogFormatError(f"{self.source}: {name} has non-finite samples")
            array.flags.writeable = False
            object.__setattr__(self, name, array)
        if n < 5:
            raise LogFormatError(f"{self.source}: {n} samples; a log needs at least 5")
        steps = np.diff(self.time_s)
        period = float(np.median(steps))
        if not period > 0 or np.max(np.abs(steps - period)) > 1e-3 * period:
            raise LogFormatError(f"{self.source}: time_s must be uniformly spaced")

    @property
    def period_s(self) -> float:
        return float((self.time_s[-1] - self.time_s[0]) / (len(self.time_s) - 1))

    def __len__(self) -> int:
        return len(self.time_s)

    def window(self, start: int, stop: int) -> JointLog:
        """Samples start..stop-1 as a log of their own."""
        return JointLog(
            self.time_s[start:stop],
            self.goal_rad[start:stop],
            self.motor_angle_rad[start:stop],
            self.link_angle_rad[start:stop],
            self.motor_velocity_rad_s[start:stop],
            self.motor_current_a[start:stop],
            source=self.source,
        )

    @classmethod
    def from_log_columns(
        cls,
        columns: Mapping[str, np.ndarray],
        joint: str | None = None,
        *,
        source: str = "log",
    ) -> JointLog:
        """The longest stretch of a run log in which the actuator followed goals.

        columns: what hil.output.read_log returns. joint: the joint's name in a multi-joint
        log (columns `goal_rad[name]`, ...); None for a single-joint log.
        A sample k belongs to the stretch if a goal is in force over tick k (a goal was sent at
        or before it), torque is on at k+1 (so it was on over the tick), every signal at k is
        finite, and tick k follows tick k-1 by one period (no skipped ticks).
        """

        def column(name: str) -> np.ndarray:
            key = name if joint is None else f"{name}[{joint}]"
            if key not in columns:
                raise LogFormatError(f"{source}: no column {key!r}")
            return np.asarray(columns[key], dtype=float)

        if "time_s" not in columns:
            raise LogFormatError(f"{source}: no column 'time_s'")
        time_s = np.asarray(columns["time_s"], dtype=float)
        signals = {name: column(name) for name in SIGNAL_COLUMNS}
        torque = column("torque_enabled")
        goal = _hold_last_goal(signals["goal_rad"])
        n = len(time_s)
        if n < 2:
            raise LogFormatError(f"{source}: fewer than two rows")
        period = float(np.median(np.diff(time_s)))
        measured = np.ones(n, dtype=bool)
        for name in SIGNAL_COLUMNS[1:]:
            measured &= np.isfinite(signals[name])
        gap = np.ones(n, dtype=bool)  # True where sample k does not follow k-1 by one period
        gap[1:] = np.abs(np.diff(time_s) - period) > 1e-3 * period
        # Tick k is usable if its goal, its start and its outcome (sample k+1, one period
        # later, torque still on) are all known.
        usable = np.zeros(n, dtype=bool)
        usable[:-1] = (
            np.isfinite(goal[:-1]) & measured[:-1] & measured[1:] & ~gap[1:] & (torque[1:] > 0.5)
        )
        start, stop = _longest_run(usable, gap)
        if stop - start < MIN_SAMPLES:
            raise LogFormatError(
                f"{source}: the longest stretch with torque on and goals sent has "
                f"{stop - start} samples; the fit needs at least {MIN_SAMPLES}"
            )
        stop += 1  # include the sample that measures the last tick's outcome
        return cls(
            time_s[start:stop],
            goal[start:stop],
            signals["motor_angle_rad"][start:stop],
            signals["link_angle_rad"][start:stop],
            signals["motor_velocity_rad_s"][start:stop],
            signals["motor_current_a"][start:stop],
            source=source,
        )


def _hold_last_goal(goal: np.ndarray) -> np.ndarray:
    """A row that sent no goal (NaN) keeps the previous goal in force (the device holds it)."""
    held = goal.copy()
    sent = np.isfinite(held)
    index = np.where(sent, np.arange(len(held)), -1)
    np.maximum.accumulate(index, out=index)
    held[index >= 0] = goal[index[index >= 0]]
    return held


def _longest_run(usable: np.ndarray, gap: np.ndarray) -> tuple[int, int]:
    """[start, stop) of the longest run of usable samples with no gap inside it."""
    best = (0, 0)
    start: int | None = None
    for k in range(len(usable) + 1):
        if k < len(usable) and usable[k] and start is not None and not gap[k]:
            continue
        if start is not None and k - start > best[1] - best[0]:
            best = (start, k)
        start = k if k < len(usable) and usable[k] else None
    return best


@dataclass(frozen=True)
class KnownJointFigures:
    """What the fit is told rather than what it finds (see the package docstring for why).

    link_inertia_kg_m2: the link's inertia about the joint axis (Sm = 1/I of (19)). It sets the
      absolute scale of K and D: an error in it passes one to one into both.
    gravity_moment_kg_m: m r of link plus load; gravity torque = g m r cos(link angle).
    torque_constant_nm_per_a: output torque per ampere of motor current (data sheet).
    current_limit_a: the actuator's current limit (its Torque Limit register), if known; used
      only to keep the model's current within it and to report it.
    velocity_limit_rad_s: the servo's speed cap (Velocity Limit register), if known.
    """

    link_inertia_kg_m2: float
    gravity_moment_kg_m: float
    torque_constant_nm_per_a: float = H54_TORQUE_CONSTANT_NM_PER_A
    gravity_m_s2: float = STANDARD_GRAVITY_M_S2
    current_limit_a: float | None = None
    velocity_limit_rad_s: float | None = None

    def __post_init__(self) -> None:
        for name in (
            "link_inertia_kg_m2",
            "gravity_moment_kg_m",
            "torque_constant_nm_per_a",
            "gravity_m_s2",
            "current_limit_a",
            "velocity_limit_rad_s",
        ):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, float(value))
        for name in ("link_inertia_kg_m2", "torque_constant_nm_per_a", "gravity_m_s2"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be finite and > 0, got {value}")
        if not (math.isfinite(self.gravity_moment_kg_m) and self.gravity_moment_kg_m >= 0):
            raise ValueError(f"gravity_moment_kg_m must be >= 0, got {self.gravity_moment_kg_m}")
        for name in ("current_limit_a", "velocity_limit_rad_s"):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be None or > 0, got {value}")

    @property
    def gravity_torque_nm(self) -> float:
        """g m r: the gravity torque with the link horizontal."""
        return self.gravity_m_s2 * self.gravity_moment_kg_m

    @property
    def current_limit_torque_nm(self) -> float:
        """The current limit as a torque (inf if unknown)."""
        if self.current_limit_a is None:
            return math.inf
        return self.current_limit_a * self.torque_constant_nm_per_a
