"""What the robot's own sensors say of a walk, from a run's log (Kim et al., ICRA 2018, Sec. IV-C).

`WalkingKinematics` reads, per log row, the measured link angles and the two feet's
force/torque sensors through the controller's model (hil/experiments/legs.py): the ZMP from the
feet's wrenches, their poses from the link angles with the foot that has carried the robot
longest (the stance foot of the latest single support) flat at its planned placement - what the
robot itself knows, as the lab's estimator does; the soles in contact (a foot carrying more than
CONTACT_SHARE of the weight) and their support polygon; the pelvis tilt. The walking metrics
(walking.py) and figures (walking_figures.py) are computed from it:

    fall_time_s         the ZMP outside the polygon by FALL_MARGIN_M, or the feet carrying less
                        than half the weight, for FALL_TIME_S; or the pelvis tilted over
                        FALL_TILT_RAD
    steps_completed     footsteps whose foot left the ground in its swing (LIFTED_FRACTION of
                        it), then took at least LANDED_SHARE of the weight before the next
                        lift-off, with the robot not fallen by then
    stopped_at_s        (a function of the run) the first safety stop, experiment time
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from drivers.joint_bus import wrench_keys
from hil.experiments.base import World
from hil.experiments.legs import (
    FEET,
    GRAVITY_M_S2,
    anchor_feet,
    leg_model,
    pelvis_rotation,
    placed_configuration,
)
from hil.output.rundir import RunData

CONTACT_SHARE = 0.05
LANDED_SHARE = 0.3
LIFTED_FRACTION = 0.5  # of its single support, a swing foot off the ground
FALL_MARGIN_M = 0.01
FALL_TIME_S = 0.1
FALL_TILT_RAD = 0.3


class PlannedWalk(Protocol):
    """What the metrics read of a walking experiment (hil/experiments/walking.py)."""

    @property
    def name(self) -> str: ...

    @property
    def n_steps(self) -> int: ...

    @property
    def object_footstep(self) -> int | None: ...

    @property
    def world(self) -> World: ...

    @property
    def plan(self) -> Any: ...  # controller.walking.FootstepPlan

    @property
    def pattern(self) -> Any: ...  # controller.walking.WalkingPattern


@dataclass(frozen=True)
class WalkingKinematics:
    """Per log row from the experiment's start, from the measured link angles and the foot
    sensors (module docstring): rows (n,) which rows of the log, time_s (experiment time), zmp_m and
    desired_zmp_m (n, 2), vertical_n (n, 2) per foot, tilt_rad (n,), com_m (n, 3),
    sole_centre_m (n, 2, 3) and sole_yaw_rad (n, 2), margin_m (n,) the ZMP's distance inside
    the support polygon of the soles in contact (negative: outside); in the plan's frame."""

    rows: np.ndarray
    time_s: np.ndarray
    zmp_m: np.ndarray
    desired_zmp_m: np.ndarray
    vertical_n: np.ndarray
    tilt_rad: np.ndarray
    com_m: np.ndarray
    sole_centre_m: np.ndarray
    sole_yaw_rad: np.ndarray
    margin_m: np.ndarray
    links_rad: np.ndarray
    weight_n: float
    period_s: float

    @classmethod
    def of(cls, run: RunData, experiment: PlannedWalk) -> WalkingKinematics:
        from controller.humanoid import FootWrench, NoSupportError, zmp_from_foot_wrenches

        model = leg_model()
        pattern = experiment.pattern
        time_s = run.time_s - run.experiment_start_s
        keep = time_s >= -1e-9
        time_s = time_s[keep]
        links = np.column_stack(run.per_joint("link_angle_rad"))[keep]
        wrench = {
            foot: np.column_stack([run.columns[k] for k in wrench_keys(foot)])[keep]
            for foot in FEET
        }
        n = time_s.size
        ticks = np.clip(np.rint(time_s / pattern.dt_s).astype(int), 0, pattern.n_ticks - 1)
        anchors = anchor_feet(pattern)
        zmp = np.full((n, 2), np.nan)
        vertical = np.zeros((n, 2))
        tilt = np.full(n, np.nan)
        com = np.full((n, 3), np.nan)
        soles = np.full((n, 2, 3), np.nan)
        yaws = np.full((n, 2), np.nan)
        half = [box.size_m[:2] / 2.0 for box in model.sole_boxes]
        weight = model.total_mass_kg * GRAVITY_M_S2
        margin = np.full(n, np.nan)
        for k in range(n):
            if not np.isfinite(links[k]).all():
                continue
            tick = ticks[k]
            anchor = anchors[tick]
            q = placed_configuration(model, links[k], anchor, pattern, tick)
            rotation = pelvis_rotation(q)
            tilt[k] = math.acos(max(-1.0, min(1.0, rotation[2, 2])))
            feet = []
            for side, foot in enumerate(FEET):
                sole = model.sole_placement(side)
                soles[k, side] = sole.translation
                yaws[k, side] = math.atan2(sole.rotation[1, 0], sole.rotation[0, 0])
                w = wrench[foot][k]
                if np.isfinite(w).all():
                    placement = model.ft_sensor_placement(side)
                    feet.append(FootWrench(w[:3], w[3:], placement.translation, placement.rotation))
                    vertical[k, side] = (placement.rotation @ w[:3])[2]
            with contextlib.suppress(NoSupportError, ValueError):
                zmp[k] = zmp_from_foot_wrenches(feet)
            contact = [s for s in (0, 1) if vertical[k, s] > CONTACT_SHARE * weight]
            if contact and np.isfinite(zmp[k]).all():
                margin[k] = polygon_margin(zmp[k], soles[k], yaws[k], half, contact)
            com[k] = model.centre_of_mass(q)
        desired = pattern.zmp_reference_m[ticks]
        period = float(np.median(np.diff(time_s))) if n > 1 else pattern.dt_s
        rows = np.flatnonzero(keep)
        return cls(
            rows, time_s, zmp, desired, vertical, tilt, com, soles, yaws, margin, links, weight,
            period,
        )  # fmt: skip

    def fall_time_s(self) -> float | None:
        """When the robot fell (module docstring), None if it did not."""
        started = self.time_s >= 0.0
        window = max(1, round(FALL_TIME_S / self.period_s))
        outside = started & ~(self.margin_m >= -FALL_MARGIN_M)
        unloaded = started & (self.vertical_n.sum(axis=1) < 0.5 * self.weight_n)
        candidates = []
        for bad in (outside, unloaded):
            runs = np.convolve(bad.astype(int), np.ones(window, dtype=int), mode="valid")
            hits = np.flatnonzero(runs >= window)
            if hits.size:
                candidates.append(float(self.time_s[hits[0]]))
        tilted = np.flatnonzero(started & (self.tilt_rad > FALL_TILT_RAD))
        if tilted.size:
            candidates.append(float(self.time_s[tilted[0]]))
        return min(candidates) if candidates else None

    def steps_completed(self, experiment: PlannedWalk, fell_at: float | None) -> int:
        """Footsteps the robot really took (module docstring), counted in order: the first that
        was not taken ends the count; `fell_at`: none counts that ends after it."""
        timeline = experiment.pattern.timeline
        dt = experiment.pattern.dt_s
        contact = self.vertical_n > CONTACT_SHARE * self.weight_n
        count = 0
        segments = timeline.segments
        for index, segment in enumerate(segments):
            if segment.footstep_index is None or segment.kind.value != "single_support":
                continue
            side = segment.landing_side.index
            after = segments[index + 1]  # the double support after its touchdown
            swing = (self.time_s >= segment.start_tick * dt) & (self.time_s < segment.end_tick * dt)
            landed = (self.time_s >= after.start_tick * dt) & (self.time_s < after.end_tick * dt)
            done_by_s = after.end_tick * dt
            covered = self.time_s.size and self.time_s[-1] >= done_by_s - 2 * dt
            lifted = swing.any() and np.mean(~contact[swing, side]) >= LIFTED_FRACTION
            loaded = landed.any() and np.any(
                self.vertical_n[landed, side] > LANDED_SHARE * self.weight_n
            )
            standing = fell_at is None or fell_at >= done_by_s
            if not (covered and lifted and loaded and standing):
                break
            count += 1
        return count

    def object_foot_height_m(self, experiment: PlannedWalk) -> float | None:
        """The height of the object's foot above the other sole, as the robot's kinematics see
        it, in the double support after it landed on the object (the median)."""
        index = experiment.object_footstep
        if index is None:
            return None
        timeline = experiment.pattern.timeline
        dt = experiment.pattern.dt_s
        side = experiment.plan.footsteps[index].side.index
        segment = next(
            s
            for s in timeline.segments
            if s.kind.value == "double_support"
            and s.footstep_index == index
            and s.landing_side is not None
        )
        rows = (self.time_s >= segment.start_tick * dt) & (self.time_s < segment.end_tick * dt)
        if not rows.any():
            return None
        height = self.sole_centre_m[rows, side, 2] - self.sole_centre_m[rows, 1 - side, 2]
        height = height[np.isfinite(height)]
        return float(np.median(height)) if height.size else None


def stopped_at_s(run: RunData) -> float | None:
    """Experiment time of the run's first safety stop (None: none): the supervisor's events in
    events.jsonl carry the reaction it took ("action"; its notices do not), and every reaction
    ends the controller's walk (hold, back off and torque off at once; finish_step at the
    double support it walks on to)."""
    times = [float(e["time_s"]) for e in run.events if e.get("action") and "time_s" in e]
    return min(times) - run.experiment_start_s if times else None


def _sole_corners(centre: np.ndarray, yaw: float, half: np.ndarray) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    rotation = np.array([[c, -s], [s, c]])
    offsets = np.array([[dx, dy] for dx in (-half[0], half[0]) for dy in (-half[1], half[1])])
    return centre[:2] + offsets @ rotation.T


def polygon_margin(
    point: np.ndarray,
    soles: np.ndarray,
    yaws: np.ndarray,
    half: Sequence[np.ndarray],
    contact: Sequence[int],
) -> float:
    """Distance of `point` inside the convex hull of the contacting soles (negative outside)."""
    from scipy.spatial import ConvexHull

    corners = np.vstack([_sole_corners(soles[s], yaws[s], half[s]) for s in contact])
    hull = ConvexHull(corners)
    return float(-np.max(hull.equations[:, :2] @ point + hull.equations[:, 2]))


def rms(values: np.ndarray) -> float | None:
    values = np.asarray(values, dtype=float)
    values = values[np.isfinite(values)]
    return float(np.sqrt(np.mean(values**2))) if values.size else None


def largest(values: np.ndarray) -> float | None:
    values = np.asarray(values, dtype=float)
    values = values[np.isfinite(values)]
    return float(values.max()) if values.size else None
