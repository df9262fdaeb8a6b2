"""Experiments of a fixed-base robot of flexible joints (any URDF robot: hil/robots/fixed_base/;
ROBOTIS's MANIPULATOR-H has its own instances, hil/robots/manipulator_h/experiments.py).

    JointPoseExperiment  the reference: a start pose and cosine moves between poses, one angle
                         per joint (one number: every joint the same), the robot placed at the
                         start pose at power-on
    HoldExperiment       hold a pose against gravity: what each joint's link is off its
                         reference once settled (the deflection the gravity compensator
                         removes, per joint), and each gear's deflection
    PushExperiment       a hold with a push at the tool (`World.tool_pushes`): the first peak
                         the push drives the joints to and how long they take to settle
    TrajectoryExperiment a joint-space trajectory (the cosine moves): how far the links lag it
    ArmContactExperiment the tool driven into a block (arm_contact.py: the testbed contact's
                         metrics)

Metrics of the hold (over the last HOLD_WINDOW_S of the run, loop time):
    static_error_rad           the largest |link - reference| of any joint (its mean over the
                               window), and per joint `static_error_rad_by_joint` (signed)
    deflection_rad_by_joint    each gear's mean deflection link - motor over the window
Of a push (experiment time from the first push's start; the error is link - reference less
its mean over the PRE_PUSH_S before the push, any joint):
    first_peak_rad             the largest |error| within PEAK_WINDOW_S of the push's start
    settling_s                 from the push's end until every joint's error stays within
                               SETTLE_BAND_RAD of its final value (its mean over the last
                               HOLD_WINDOW_S; None: not before the run ends)
Of a trajectory (the whole experiment):
    tracking_rms_rad           the largest of the joints' rms link - reference
    tracking_peak_rad          the largest |link - reference| of any joint
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from hil.experiments.base import Experiment, World
from hil.output.records import UNMEASURED
from hil.output.report import Column, number
from hil.output.rundir import RunData

HOLD_WINDOW_S = 1.0
PRE_PUSH_S = 0.5
PEAK_WINDOW_S = 1.0
SETTLE_BAND_RAD = 1e-3  # 1 mrad: a third of the testbed's static deflection (m g r / K)

Pose = float | tuple[float, ...]


def _pose(pose: Pose) -> np.ndarray:
    return np.asarray(pose, dtype=float)


@dataclass(frozen=True)
class JointMove:
    """A cosine move of every joint from `start_rad` to `end_rad` between two times."""

    start_s: float
    duration_s: float
    start_rad: Pose
    end_rad: Pose

    def value(self, time_s: float) -> np.ndarray:
        start, end = _pose(self.start_rad), _pose(self.end_rad)
        if time_s <= self.start_s:
            return start
        if time_s >= self.start_s + self.duration_s:
            return end
        phase = (time_s - self.start_s) / self.duration_s
        return start + (end - start) * 0.5 * (1 - math.cos(math.pi * phase))


@dataclass(frozen=True)
class JointPoseExperiment(Experiment):
    """A fixed-base robot's experiment: `start_rad`, then `moves` in turn (module docstring)."""

    name: str
    title: str
    duration_s: float
    start_rad: Pose
    moves: tuple[JointMove, ...] = ()
    world: World = World()

    def reference(self, time_s: float) -> float | np.ndarray:
        value = _pose(self.start_rad)
        for move in self.moves:
            if time_s >= move.start_s:
                value = move.value(time_s)
        return value if value.ndim else float(value)

    def parameters(self) -> dict[str, Any]:
        return {"start_rad": np.atleast_1d(_pose(self.start_rad)).tolist()}


def settled_window(run: RunData, window_s: float = HOLD_WINDOW_S) -> np.ndarray:
    """The ticks of the run's last `window_s` (a mask)."""
    time = run.time_s
    return time >= time[-1] - window_s if time.size else np.zeros(0, dtype=bool)


def per_joint_means(run: RunData, window: np.ndarray) -> tuple[dict[str, float], dict[str, float]]:
    """Each joint's mean link error (link - reference) and deflection (link - motor)."""
    errors, deflections = {}, {}
    for joint in run.joint_names:
        link = run.signal("link_angle_rad", joint)
        error = (link - run.signal("reference_rad", joint))[window]
        deflection = (link - run.signal("motor_angle_rad", joint))[window]
        label = joint or "joint"
        errors[label] = float(np.nanmean(error)) if np.isfinite(error).any() else math.nan
        deflections[label] = (
            float(np.nanmean(deflection)) if np.isfinite(deflection).any() else math.nan
        )
    return errors, deflections


@dataclass(frozen=True)
class HoldExperiment(JointPoseExperiment):
    """Hold `start_rad` against gravity (module docstring)."""

    def metrics(self, run: RunData) -> dict[str, Any]:
        window = settled_window(run)
        if not window.any() or run.time_s[-1] - run.experiment_start_s < HOLD_WINDOW_S:
            return {
                "static_error_rad": None,
                UNMEASURED: {"static_error_rad": f"a hold shorter than {HOLD_WINDOW_S:g} s"},
            }
        errors, deflections = per_joint_means(run, window)
        finite = [abs(e) for e in errors.values() if math.isfinite(e)]
        metrics: dict[str, Any] = {
            "static_error_rad": max(finite) if finite else None,
            "static_error_rad_by_joint": _finite_or_none(errors),
            "deflection_rad_by_joint": _finite_or_none(deflections),
        }
        if not finite:
            metrics[UNMEASURED] = {"static_error_rad": "no valid link reading once settled"}
        return metrics

    @property
    def report_columns(self) -> tuple[Column, ...]:
        return (Column("static_error_rad", "static error [rad]", number(".4f")),)


def _finite_or_none(values: dict[str, float]) -> dict[str, float | None]:
    return {k: (v if math.isfinite(v) else None) for k, v in values.items()}


def _experiment_time(run: RunData) -> np.ndarray:
    return run.time_s - run.experiment_start_s


def _errors(run: RunData) -> np.ndarray:
    """link - reference, (ticks, joints)."""
    return np.column_stack(
        [
            run.signal("link_angle_rad", joint) - run.signal("reference_rad", joint)
            for joint in run.joint_names
        ]
    )


@dataclass(frozen=True)
class PushExperiment(HoldExperiment):
    """Hold `start_rad` while `world.tool_pushes` push at the tool (module docstring)."""

    def metrics(self, run: RunData) -> dict[str, Any]:
        metrics = super().metrics(run)
        push = self.world.tool_pushes[0]
        time = _experiment_time(run)
        error = _errors(run)
        before = (time >= push.start_s - PRE_PUSH_S) & (time < push.start_s)
        during = (time >= push.start_s) & (time < push.start_s + PEAK_WINDOW_S)
        if not before.any() or not during.any():
            metrics["first_peak_rad"] = metrics["settling_s"] = None
            metrics.setdefault(UNMEASURED, {})["first_peak_rad"] = "the run ends before the push"
            return metrics
        off = np.abs(error - np.nanmean(error[before], axis=0)).max(axis=1)
        metrics["first_peak_rad"] = float(np.nanmax(off[during]))
        end = push.start_s + push.duration_s
        final = np.nanmean(error[settled_window(run)], axis=0)
        from_final = np.abs(error - final).max(axis=1)
        outside = np.flatnonzero((time >= end) & ~(from_final < SETTLE_BAND_RAD))
        after = np.flatnonzero(time >= end)
        settled = after.size and (not outside.size or outside[-1] < after[-1])
        metrics["settling_s"] = (
            float(time[outside[-1] + 1] - end if outside.size else 0.0) if settled else None
        )
        return metrics

    @property
    def report_columns(self) -> tuple[Column, ...]:
        return (
            *super().report_columns,
            Column("first_peak_rad", "first peak [rad]", number(".4f")),
            Column("settling_s", "settling [s]", number(".2f")),
        )


@dataclass(frozen=True)
class TrajectoryExperiment(JointPoseExperiment):
    """Follow the cosine moves `moves` (module docstring)."""

    def metrics(self, run: RunData) -> dict[str, Any]:
        error = _errors(run)[_experiment_time(run) >= 0.0]
        if not np.isfinite(error).any():
            return {
                "tracking_rms_rad": None,
                UNMEASURED: {"tracking_rms_rad": "no valid link reading"},
            }
        return {
            "tracking_rms_rad": float(np.nanmax(np.sqrt(np.nanmean(error**2, axis=0)))),
            "tracking_peak_rad": float(np.nanmax(np.abs(error))),
        }

    @property
    def report_columns(self) -> tuple[Column, ...]:
        return (
            Column("tracking_rms_rad", "tracking rms [rad]", number(".4f")),
            Column("tracking_peak_rad", "tracking peak [rad]", number(".4f")),
        )
