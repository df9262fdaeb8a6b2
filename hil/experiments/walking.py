"""DYROS-JET walking (Kim et al., ICRA 2018, Sec. IV-C, Figs. 7 and 8).

    walk-slow       4 steps of 0.2 m, 0.8 s single / 3.2 s double support (the paper's "slow")
    walk-dynamic    4 steps of 0.2 m, 0.8 s single / 0.3 s double support (its "dynamic")
    step-on-object  6 steps of 0.2 m at the dynamic timing; a box of OBJECT_HEIGHT_M lies under
                    the third footstep (the right foot's second), which the plan does not know

Why these numbers: the paper gives the timings, not the number of steps nor their length.
Four steps (right, left, right, closing left) contain every phase of a walk - the start, a
middle step on each foot and the stop - and keep a slow run at 21.3 s. The object's run needs
steps after the object (the robot must keep walking): six steps, the fourth to sixth after it.
0.2 m is the length the lab's planner uses; it also leaves the box clear of the right foot's
placements before and after it (a foot is 0.30 m long, the right foot moves 0.4 m a step).

The reference of every joint is the walking pattern (`controller.walking.WalkingPattern`):
Kajita's ZMP preview control on the cart-table, quintic swing feet, closed-form leg IK, the
pelvis solved so that the robot model's CoM (pinocchio, from the URDF) is the planned CoM. It
starts with a rest of 1.6 s (the preview horizon, and longer than the second the robot needs
to settle on its springs) from the walking-ready posture the robot stands in at power-on, and
ends with a rest. The plan's frame is the one the robot starts in: the middle of its soles at
the origin, x forward. `support(t)` follows the pattern's timeline; `kdist_at` is the lab's
schedule (`controller.walking.KdistSchedule`): the run's Kdist (the lab's 0.2) on the stance
leg, 1.0 on the landing leg around its touchdown, the controller ramping between them.

What is measured, from the robot's own sensors in the log (`WalkingKinematics`): the ZMP from
the two feet's force/torque sensors, their poses from the measured link angles with the foot
that has carried the robot longest (the stance foot of the latest single support) flat at its
planned placement - what the robot itself knows, as the lab's estimator does; the soles in
contact (a foot carrying more than CONTACT_SHARE of the weight) and their support polygon; the
pelvis tilt. Metrics, over the walk (first double support to the end of the final one):

    zmp_rms_error_m, zmp_max_error_m      |measured - desired ZMP|, rms and largest
    *_lateral_m, *_sagittal_m             the same for y (lateral) and x (sagittal) alone
    zmp_at_edge_s                         time with the measured ZMP within EDGE_MARGIN_M of the
                                          support polygon's edge, or outside it
    fell                                  the ZMP outside the polygon by FALL_MARGIN_M, or the
                                          feet carrying less than half the weight, for
                                          FALL_TIME_S; or the pelvis tilted over FALL_TILT_RAD
    steps_completed                       footsteps whose foot left the ground in its swing,
                                          then took at least LANDED_SHARE of the weight before
                                          the next lift-off, with the robot not fallen by then
    stopped_early                         the run ended (a safety stop) before the walk's end
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from drivers.joint_bus import wrench_keys
from hil.experiments.base import Experiment, FloorObject, World
from hil.output.plots import ComparisonRun, WorldMarks
from hil.output.records import RunEntry
from hil.output.report import Column, Missing, Relation, check, find, metric, number
from hil.output.rundir import RunData
from hil.vocabulary import ControllerKind

FEET = ("left_foot", "right_foot")
GRAVITY_M_S2 = 9.81
SLOW_TIMING_S = (0.8, 3.2)  # single, double support (Sec. IV-C)
DYNAMIC_TIMING_S = (0.8, 0.3)
INITIAL_REST_S = 1.6  # the preview horizon (Kajita's 1.6 s)
FINAL_REST_S = 0.5
STEP_LENGTH_M = 0.2
# The walking-ready posture's soles (controller.humanoid.WALKING_READY_TARGET): 0.2556 m apart.
SOLE_LATERAL_OFFSET_M = 0.1278
OBJECT_HEIGHT_M = 0.015
OBJECT_FOOTSTEP = 2  # the right foot's second step
OBJECT_MARGIN_M = 0.02  # the box reaches this far beyond the planned sole on every side
ZMP_CLAIM_M = 0.02  # "The ZMP tracking error was within 2cm" (Sec. V)
CONTACT_SHARE = 0.05
LANDED_SHARE = 0.3
LIFTED_FRACTION = 0.5  # of its single support, a swing foot off the ground
EDGE_MARGIN_M = 0.01
FALL_MARGIN_M = 0.01
FALL_TIME_S = 0.1
FALL_TILT_RAD = 0.3


@functools.lru_cache(maxsize=1)
def _leg_model():
    from controller.humanoid import LegModel
    from hil.config import load_config, robot_description_text

    return LegModel(robot_description_text(load_config(robot="dyros-jet")))


def _support_state(support: Any) -> Any:
    from controller.humanoid import SupportState

    return SupportState(support.value)


@dataclass(frozen=True)
class WalkingExperiment(Experiment):
    """Walk a straight footstep plan (see the module docstring)."""

    __test__ = False

    name: str
    title: str
    single_support_s: float
    double_support_s: float
    n_steps: int
    step_length_m: float = STEP_LENGTH_M
    world: World = World()
    object_footstep: int | None = None  # the footstep the world's object lies under

    # --- the plan and its pattern ----------------------------------------------------------
    @functools.cached_property
    def plan(self) -> Any:
        """The footsteps (ankle ground projections) in the plan's frame: the robot's soles
        start at (0, +-SOLE_LATERAL_OFFSET_M); the ankle is SOLE_CENTRE_AHEAD_OF_ANKLE_M
        behind its sole's centre."""
        from controller.walking import StepTiming, straight_walk_plan
        from controller.walking.dyros_jet_figures import SOLE_CENTRE_AHEAD_OF_ANKLE_M

        timing = StepTiming(
            self.single_support_s, self.double_support_s, INITIAL_REST_S, FINAL_REST_S
        )
        plan = straight_walk_plan(
            self.n_steps, self.step_length_m, timing, lateral_foot_offset_m=SOLE_LATERAL_OFFSET_M
        )

        def shifted(step: Any) -> Any:
            return dataclasses.replace(step, x_m=step.x_m - SOLE_CENTRE_AHEAD_OF_ANKLE_M)

        return dataclasses.replace(
            plan,
            initial_left=shifted(plan.initial_left),
            initial_right=shifted(plan.initial_right),
            footsteps=tuple(shifted(s) for s in plan.footsteps),
        )

    @functools.cached_property
    def pattern(self) -> Any:
        """The walking pattern on the 200 Hz grid, the ZMP reference at the soles' centres and
        the CoM at the walking-ready posture's height (so tick 0 is that posture)."""
        from controller.humanoid import LEG_JOINT_NAMES, WALKING_READY_LEG_ANGLES_RAD
        from controller.walking import (
            LegGeometry,
            LegsGeometry,
            PinocchioCenterOfMass,
            WalkingParams,
            WalkingPattern,
            ZmpReferenceParams,
            ZmpTransition,
        )
        from controller.walking.dyros_jet_figures import SOLE_CENTRE_AHEAD_OF_ANKLE_M

        model = _leg_model()
        q = model.standing_configuration(np.asarray(WALKING_READY_LEG_ANGLES_RAD), side=0)
        com_height = float(model.centre_of_mass(q)[2])
        legs = LegsGeometry(
            LegGeometry.from_pinocchio(model.model, LEG_JOINT_NAMES[:6]),
            LegGeometry.from_pinocchio(model.model, LEG_JOINT_NAMES[6:]),
        )
        params = WalkingParams(
            com_height_m=com_height,
            zmp=ZmpReferenceParams(
                transition=ZmpTransition.SMOOTH, forward_offset_m=SOLE_CENTRE_AHEAD_OF_ANKLE_M
            ),
        )
        com = PinocchioCenterOfMass(model.model, LEG_JOINT_NAMES)
        return WalkingPattern(self.plan, params, legs=legs, com_model=com)

    @property
    def duration_s(self) -> float:  # type: ignore[override]
        return float(self.plan.duration_s)

    def _tick(self, time_s: float) -> int:
        n = self.pattern.n_ticks
        return min(n - 1, max(0, int(round(time_s / self.pattern.dt_s))))

    # --- what the loop asks ----------------------------------------------------------------
    def reference(self, time_s: float) -> np.ndarray:
        return self.pattern.joint_angles_rad[self._tick(time_s)]

    def reference_table(self, period_s: float, ticks: int, n_joints: int) -> np.ndarray:
        times = np.arange(ticks) * period_s
        index = np.clip(np.rint(times / self.pattern.dt_s).astype(int), 0, self.pattern.n_ticks - 1)
        return self.pattern.joint_angles_rad[index].copy()

    def reference_range(self, n_joints: int) -> tuple[np.ndarray, np.ndarray]:
        angles = self.pattern.joint_angles_rad
        return angles.min(axis=0), angles.max(axis=0)

    def phase(self, time_s: float) -> str:
        return self.pattern.timeline.phase(self._tick(time_s)).kind.value

    def support(self, time_s: float) -> object:
        return _support_state(self.pattern.timeline.phase(self._tick(time_s)).support)

    def kdist_at(self, time_s: float, kdist: float) -> np.ndarray | None:
        from controller.walking import KdistSchedule, kdist_per_joint

        schedule = KdistSchedule(stance_gain=kdist)
        return kdist_per_joint(self.pattern.timeline.phase(self._tick(time_s)), schedule)

    # --- after a run -----------------------------------------------------------------------
    @property
    def walk_ticks(self) -> tuple[int, int]:
        """The walk on the pattern's grid: first double support to the end of the final one."""
        segments = self.pattern.timeline.segments
        return segments[1].start_tick, segments[-1].start_tick

    def metrics(self, run: RunData) -> dict[str, Any]:
        kinematics = WalkingKinematics.of(run, self)
        start, end = (t * self.pattern.dt_s for t in self.walk_ticks)
        stopped_at = _stopped_at_s(run)
        until = end if stopped_at is None else min(end, stopped_at)
        # the controller's walk: after a safety stop the loop only holds the robot
        walking = (kinematics.time_s >= start) & (kinematics.time_s < until)
        error = kinematics.zmp_m - kinematics.desired_zmp_m
        fell_at = kinematics.fall_time_s()
        metrics: dict[str, Any] = {
            "zmp_rms_error_m": _rms(np.linalg.norm(error, axis=1)[walking]),
            "zmp_max_error_m": _max(np.linalg.norm(error, axis=1)[walking]),
            "zmp_rms_error_lateral_m": _rms(error[walking, 1]),
            "zmp_max_error_lateral_m": _max(np.abs(error[walking, 1])),
            "zmp_rms_error_sagittal_m": _rms(error[walking, 0]),
            "zmp_max_error_sagittal_m": _max(np.abs(error[walking, 0])),
            "zmp_at_edge_s": float(
                np.count_nonzero(walking & ~(kinematics.margin_m >= EDGE_MARGIN_M))
                * kinematics.period_s
            ),
            "fell": fell_at is not None,
            "fell_at_s": fell_at,
            "steps_completed": kinematics.steps_completed(
                self, fell_at if stopped_at is None else min(stopped_at, fell_at or math.inf)
            ),
            "stopped_at_s": stopped_at,
            "stopped_early": bool(
                kinematics.time_s.size == 0 or kinematics.time_s[-1] < end or until < end
            ),
        }
        if self.object_footstep is not None:  # only once the robot stepped on it
            stepped = metrics["steps_completed"] > self.object_footstep
            metrics["object_foot_height_m"] = (
                kinematics.object_foot_height_m(self) if stepped else None
            )
        return metrics

    def marks(self, run: RunData) -> WorldMarks:
        return WorldMarks(title=self.title, experiment=self.name)

    @property
    def report_columns(self) -> tuple[Column, ...]:
        return (
            Column("steps_completed", "steps", number("d")),
            Column("fell", "fell", number("")),
            Column("zmp_rms_error_m", "ZMP rms [m]", number(".4f")),
            Column("zmp_rms_error_lateral_m", "rms y [m]", number(".4f")),
            Column("zmp_rms_error_sagittal_m", "rms x [m]", number(".4f")),
            Column("zmp_max_error_lateral_m", "max y [m]", number(".4f")),
            Column("zmp_max_error_sagittal_m", "max x [m]", number(".4f")),
            Column("zmp_at_edge_s", "ZMP at edge [s]", number(".2f")),
            Column("stopped_at_s", "stopped at [s]", number(".2f")),
        )

    def relations(self, entries: Sequence[RunEntry]) -> list[Relation]:
        return walking_relations(self, entries)

    def comparison_figure(
        self, runs: Sequence[ComparisonRun], path: Path, setup: str
    ) -> Path | None:
        if not runs:
            return None
        from hil.experiments import walking_figures

        if self.object_footstep is not None:
            return walking_figures.step_sequence_figure(self, runs, path, setup)
        return walking_figures.lateral_zmp_figure(self, runs, path, setup)

    @property
    def figure_name(self) -> str:
        return {"walk-slow": "fig7a_walk_slow.png", "walk-dynamic": "fig7b_walk_dynamic.png"}.get(
            self.name, "fig8_step_on_object.png"
        )


@dataclass(frozen=True)
class WalkingKinematics:
    """Per log row, from the measured link angles and the foot sensors (module docstring):
    time_s (experiment time), zmp_m and desired_zmp_m (n, 2), vertical_n (n, 2) per foot,
    tilt_rad (n,), sole_centre_m (n, 2, 3) and sole_yaw_rad (n, 2), margin_m (n,) the ZMP's
    distance inside the support polygon of the soles in contact (negative: outside)."""

    time_s: np.ndarray
    zmp_m: np.ndarray
    desired_zmp_m: np.ndarray
    vertical_n: np.ndarray
    tilt_rad: np.ndarray
    sole_centre_m: np.ndarray
    sole_yaw_rad: np.ndarray
    margin_m: np.ndarray
    links_rad: np.ndarray
    weight_n: float
    period_s: float

    @classmethod
    def of(cls, run: RunData, experiment: WalkingExperiment) -> WalkingKinematics:
        from controller.humanoid import FootWrench, NoSupportError, zmp_from_foot_wrenches

        model = _leg_model()
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
        anchors = _anchor_feet(pattern)
        zmp = np.full((n, 2), np.nan)
        vertical = np.zeros((n, 2))
        tilt = np.full(n, np.nan)
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
            q = _placed_configuration(model, links[k], anchor, pattern, tick)
            rotation = _rotation(q)
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
                margin[k] = _polygon_margin(zmp[k], soles[k], yaws[k], half, contact)
        desired = pattern.zmp_reference_m[ticks]
        period = float(np.median(np.diff(time_s))) if n > 1 else pattern.dt_s
        return cls(time_s, zmp, desired, vertical, tilt, soles, yaws, margin, links, weight, period)

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

    def steps_completed(self, experiment: WalkingExperiment, fell_at: float | None) -> int:
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

    def object_foot_height_m(self, experiment: WalkingExperiment) -> float | None:
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


def _stopped_at_s(run: RunData) -> float | None:
    """Experiment time of the run's first safety stop (None: none): the supervisor's events in
    events.jsonl carry the reaction it took ("action"; its notices do not), and every reaction
    (hold, back off, torque off) ends the controller's walk."""
    times = [float(e["time_s"]) for e in run.events if e.get("action") and "time_s" in e]
    return min(times) - run.experiment_start_s if times else None


def _anchor_feet(pattern: Any) -> np.ndarray:
    """Per pattern tick, the foot that carried the robot longest: the stance foot of the latest
    single support (before the first one, the stance foot of the first)."""
    from controller.walking import SegmentKind

    segments = pattern.timeline.segments
    singles = [s for s in segments if s.kind is SegmentKind.SINGLE_SUPPORT]
    anchors = np.empty(pattern.n_ticks, dtype=int)
    current = singles[0].landing_side.other.index
    for segment in segments:
        if segment.kind is SegmentKind.SINGLE_SUPPORT:
            current = segment.landing_side.other.index
        anchors[segment.start_tick : segment.end_tick] = current
    return anchors


def _placed_configuration(
    model: Any, links: np.ndarray, anchor: int, pattern: Any, tick: int
) -> np.ndarray:
    """pinocchio's q at these link angles with sole `anchor` flat on the ground at its planned
    place (the pattern's foot at `tick`, carried to the sole's centre), frames updated."""
    from controller.walking import yaw_rotation

    q = model.standing_configuration(links, side=anchor)  # that sole's centre at the origin
    yaw = float(pattern.foot_yaw_rad[tick, anchor])
    turn = yaw_rotation(yaw)
    sole_in_ankle = model.sole_boxes[anchor].bottom_centre_m
    ankle = pattern.foot_position_m[tick, anchor]
    sole = ankle + turn @ sole_in_ankle
    sole[2] = 0.0
    if yaw != 0.0:
        import pinocchio as pin

        rotation = turn @ _rotation(q)
        q[3:7] = pin.Quaternion(rotation).coeffs()
        q[:3] = turn @ q[:3]
    q[:3] += sole
    model.update_kinematics(q)
    return q


def _rotation(q: np.ndarray) -> np.ndarray:
    import pinocchio as pin

    return pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()


def _sole_corners(centre: np.ndarray, yaw: float, half: np.ndarray) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    rotation = np.array([[c, -s], [s, c]])
    offsets = np.array([[dx, dy] for dx in (-half[0], half[0]) for dy in (-half[1], half[1])])
    return centre[:2] + offsets @ rotation.T


def _polygon_margin(
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


def _rms(values: np.ndarray) -> float | None:
    values = np.asarray(values, dtype=float)
    values = values[np.isfinite(values)]
    return float(np.sqrt(np.mean(values**2))) if values.size else None


def _max(values: np.ndarray) -> float | None:
    values = np.asarray(values, dtype=float)
    values = values[np.isfinite(values)]
    return float(values.max()) if values.size else None


# --- the paper's claims (Sec. IV-C, V) ------------------------------------------------------
def _walked(experiment: WalkingExperiment, entry: RunEntry | None, what: str) -> tuple[bool, str]:
    """Did the run walk its whole plan (no fall, no safety stop), and a summary of it."""
    steps = metric(entry, "steps_completed", what)
    fell = metric(entry, "fell", what)
    stopped = metric(entry, "stopped_at_s", what)
    ok = not fell and stopped is None and steps == experiment.n_steps
    text = f"{steps}/{experiment.n_steps} steps"
    if stopped is not None:
        text += f", safety stop at {stopped:.2f} s"
    if fell:
        text += f", fell at {metric(entry, 'fell_at_s', what):.2f} s"
    return ok, text


def _millimetres(value: float | None) -> str:
    return "-" if value is None else f"{value * 1e3:.1f} mm"


def _rms_of(entry: RunEntry | None, what: str) -> float:
    value = metric(entry, "zmp_rms_error_m", what)
    return math.inf if value is None else float(value)


def _within_2cm(experiment: WalkingExperiment, dob: RunEntry | None) -> tuple[bool, str]:
    lateral = metric(dob, "zmp_max_error_lateral_m", "gc+lqr+dob")
    sagittal = metric(dob, "zmp_max_error_sagittal_m", "gc+lqr+dob")
    ok, steps = _walked(experiment, dob, "gc+lqr+dob")
    holds = ok and lateral <= ZMP_CLAIM_M and sagittal <= ZMP_CLAIM_M
    return holds, (
        f"gc+lqr+dob: max |error| y {_millimetres(lateral)}, x {_millimetres(sagittal)} ({steps})"
    )


def _beats(
    experiment: WalkingExperiment,
    winners: Sequence[tuple[RunEntry | None, str]],
    losers: Sequence[tuple[RunEntry | None, str]],
) -> tuple[bool, str]:
    """Each winner walked, and each loser either did not or had a larger ZMP rms."""
    holds = True
    parts = []
    for entry, what in (*winners, *losers):
        _, steps = _walked(experiment, entry, what)
        parts.append(f"{what} {_millimetres(metric(entry, 'zmp_rms_error_m', what))} ({steps})")
    for winner, win_name in winners:
        win_ok, _ = _walked(experiment, winner, win_name)
        for loser, lose_name in losers:
            lose_ok, _ = _walked(experiment, loser, lose_name)
            better = _rms_of(winner, win_name) < _rms_of(loser, lose_name)
            holds = holds and win_ok and (not lose_ok or better)
    return holds, "ZMP rms while walking: " + ", ".join(parts)


def _none_walked(experiment: WalkingExperiment, entries: Sequence[RunEntry | None]) -> bool:
    with contextlib.suppress(Missing):
        return not any(_walked(experiment, e, e.choice.label)[0] for e in entries if e)
    return False


def walking_relations(experiment: WalkingExperiment, entries: Sequence[RunEntry]) -> list[Relation]:
    """The paper's claims that concern this experiment (a walk that fell, stopped or took fewer
    steps than planned does not count as walking)."""
    exp = experiment.name
    dob = find(entries, exp, ControllerKind.GC_LQR_DOB)
    gc = find(entries, exp, ControllerKind.GC)
    lqr = find(entries, exp, ControllerKind.GC_LQR)
    pid = find(entries, exp, ControllerKind.PID)
    relations: list[Relation] = []
    if experiment.object_footstep is None:
        relations.append(
            check(
                exp,
                "GC+LQR+DOB tracks the ZMP reference within 2 cm (lateral and sagittal)",
                "Sec. V: 'The ZMP tracking error was within 2cm from the reference ZMP "
                "trajectory' (Fig. 7)",
                lambda: _within_2cm(experiment, dob),
            )
        )
    if exp == "walk-slow":
        relations.append(
            check(
                exp,
                "GC+LQR and GC+LQR+DOB track the ZMP better than GC in slow walking",
                "Sec. IV-C, Fig. 7(a): 'obviously better than those of the other controllers'",
                lambda: _beats(experiment, [(lqr, "gc+lqr"), (dob, "gc+lqr+dob")], [(gc, "gc")]),
            )
        )
    if exp == "walk-dynamic":
        pid_walked = functools.partial(_walked, experiment, pid, "pid")
        relations.append(
            check(
                exp,
                "the default walking controller cannot walk dynamically",
                "Sec. IV-C: 'the robot with the default algorithm could not walk'",
                lambda: (not pid_walked()[0], "pid: " + pid_walked()[1]),
                note="no controller walked here: this does not tell pid apart"
                if _none_walked(experiment, (dob, gc, lqr))
                else "",
            )
        )
        relations.append(
            check(
                exp,
                "GC+LQR+DOB tracks the ZMP better than GC and GC+LQR in dynamic walking",
                "Sec. IV-C, Fig. 7(b): the DOB absorbs the landing impact",
                lambda: _beats(experiment, [(dob, "gc+lqr+dob")], [(gc, "gc"), (lqr, "gc+lqr")]),
            )
        )
    if experiment.object_footstep is not None:

        def keeps_walking() -> tuple[bool, str]:
            ok, steps = _walked(experiment, dob, "gc+lqr+dob")
            height = metric(dob, "object_foot_height_m", "gc+lqr+dob")
            return ok, f"gc+lqr+dob: {steps}; the foot on the object {_millimetres(height)} up"

        relations.append(
            check(
                exp,
                "GC+LQR+DOB keeps walking after stepping on an unknown object",
                "Sec. IV-C, Fig. 8: 'walking stability was preserved'",
                keeps_walking,
                note=f"a box {OBJECT_HEIGHT_M * 1e3:.0f} mm high under footstep "
                f"{OBJECT_FOOTSTEP + 1}",
            )
        )
    return relations


# --- the experiments ------------------------------------------------------------------------
def _object_under(experiment: WalkingExperiment, index: int) -> FloorObject:
    """A box under footstep `index`'s sole, OBJECT_MARGIN_M beyond it on every side."""
    from controller.walking.dyros_jet_figures import (
        FOOT_LENGTH_M,
        FOOT_WIDTH_M,
        SOLE_CENTRE_AHEAD_OF_ANKLE_M,
    )

    step = experiment.plan.footsteps[index]
    return FloorObject(
        centre_m=(step.x_m + SOLE_CENTRE_AHEAD_OF_ANKLE_M, step.y_m),
        size_m=(
            FOOT_LENGTH_M + 2 * OBJECT_MARGIN_M,
            FOOT_WIDTH_M + 2 * OBJECT_MARGIN_M,
            OBJECT_HEIGHT_M,
        ),
    )


WALK_SLOW = WalkingExperiment(
    name="walk-slow",
    title="DYROS-JET walks slowly: 4 steps of 0.2 m, 0.8 s single / 3.2 s double support",
    single_support_s=SLOW_TIMING_S[0],
    double_support_s=SLOW_TIMING_S[1],
    n_steps=4,
)
WALK_DYNAMIC = WalkingExperiment(
    name="walk-dynamic",
    title="DYROS-JET walks dynamically: 4 steps of 0.2 m, 0.8 s single / 0.3 s double support",
    single_support_s=DYNAMIC_TIMING_S[0],
    double_support_s=DYNAMIC_TIMING_S[1],
    n_steps=4,
)
_ON_OBJECT = WalkingExperiment(
    name="step-on-object",
    title=f"DYROS-JET steps on an unknown {OBJECT_HEIGHT_M * 1e3:.0f} mm box (6 steps of 0.2 m, "
    "0.8 s / 0.3 s)",
    single_support_s=DYNAMIC_TIMING_S[0],
    double_support_s=DYNAMIC_TIMING_S[1],
    n_steps=6,
    object_footstep=OBJECT_FOOTSTEP,
)
STEP_ON_OBJECT = dataclasses.replace(
    _ON_OBJECT, world=World(floor_objects=(_object_under(_ON_OBJECT, OBJECT_FOOTSTEP),))
)
