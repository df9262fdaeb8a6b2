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

What is measured, from the robot's own sensors in the log (`WalkingKinematics`,
walking_kinematics.py): the ZMP from the two feet's force/torque sensors, the feet's poses and
the pelvis tilt from the measured link angles. Metrics, over the walk (first double support to
the end of the final one):

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

Per tick (`derived_series`): kinematics.csv in the run directory, the measured and the planned
ZMP, the CoM, the pelvis tilt, the support margin and the feet's vertical forces these metrics
are computed from (hil/output/series.py).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hil.config import Config
from hil.experiments.base import Experiment, FloorObject, ReferenceFeedback, World
from hil.experiments.legs import leg_model, on_feet, support_state
from hil.experiments.walking_kinematics import (
    WalkingKinematics,
    largest,
    rms,
    stopped_at_s,
)
from hil.experiments.walking_relations import walking_relations
from hil.output.plots import ComparisonRun, WorldMarks
from hil.output.records import RunEntry
from hil.output.report import Column, Relation, number
from hil.output.rundir import RunData
from hil.output.series import DerivedSeries, kinematics_series
from hil.vocabulary import ControllerChoice, ReactionPolicy

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
EDGE_MARGIN_M = 0.01
# The lab's ZMP reference (psh117/dyros_jet, walking_controller.cpp): each foot's point shifted
# inward by 0.02 m (`addZmpOffset`, 2018; 0.04 m on master), the double support split into its
# DSP2, rests and DSP1 with moves of t_double = 0.1 s (`parameterSetting`, `onestepZmp`).
LAB_ZMP_INWARD_OFFSET_M = 0.02
LAB_ZMP_MOVE_S = 0.1
# The lab's swing foot (walking_controller.cpp, `getFootTrajectory`): on the ground, unloaded,
# for t_rest_temp = 0.1 s at each end of the single support (it lifts 0.1 s after the ZMP has
# reached the stance foot and lands 0.1 s before the ZMP leaves it).
LAB_SWING_GUARD_S = 0.1


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
    # The ZMP reference: how far each foot's point lies inward of its sole's centre, and the
    # double support's shape (controller.walking.ZmpTransition: "lab-split", "smooth", "linear")
    zmp_inward_offset_m: float = LAB_ZMP_INWARD_OFFSET_M
    zmp_transition: str = "lab-split"
    swing_guard_s: float = 0.0  # controller.walking.WalkingParams; LAB_SWING_GUARD_S: the lab's
    # the preview's zc: the CoM above the ground (False) or, as the lab's code, above the ankle
    preview_height_above_ankle: bool = False

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
        from controller.walking.dyros_jet_figures import (
            SOLE_BELOW_ANKLE_M,
            SOLE_CENTRE_AHEAD_OF_ANKLE_M,
        )

        model = leg_model()
        q = model.standing_configuration(np.asarray(WALKING_READY_LEG_ANGLES_RAD), side=0)
        com_height = float(model.centre_of_mass(q)[2])
        legs = LegsGeometry(
            LegGeometry.from_pinocchio(model.model, LEG_JOINT_NAMES[:6]),
            LegGeometry.from_pinocchio(model.model, LEG_JOINT_NAMES[6:]),
        )
        params = WalkingParams(
            com_height_m=com_height,
            zmp=ZmpReferenceParams(
                transition=ZmpTransition(self.zmp_transition),
                forward_offset_m=SOLE_CENTRE_AHEAD_OF_ANKLE_M,
                inward_offset_m=self.zmp_inward_offset_m,
                lab_move_s=LAB_ZMP_MOVE_S,
            ),
            swing_guard_s=self.swing_guard_s,
            preview_height_m=(
                com_height - SOLE_BELOW_ANKLE_M if self.preview_height_above_ankle else None
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

    def reference_feedback(
        self, config: Config, choice: ControllerChoice
    ) -> ReferenceFeedback | None:
        """The lab's walking scheme (walking_scheme.py, `[walking]`): the CoM feedback on the
        pelvis for every controller, the position-mode terms for the default one (`pid`)."""
        from hil.experiments.walking_scheme import LabWalkingScheme

        return LabWalkingScheme.for_run(self.pattern, config, choice)

    def phase(self, time_s: float) -> str:
        return self.pattern.timeline.phase(self._tick(time_s)).kind.value

    def support(self, time_s: float) -> object:
        return support_state(self.pattern.timeline.phase(self._tick(time_s)).support)

    def reaction_policy(self) -> ReactionPolicy:
        """The robot on its feet (legs.py `on_feet`): a `finish_step` walks on to the next
        double support that shares the weight, within one step and its double support."""
        return on_feet(within_s=self.single_support_s + self.double_support_s)

    def kdist_at(self, time_s: float, kdist: float) -> np.ndarray | None:
        from controller.walking import KdistSchedule, kdist_per_joint

        # the lab's landing gain on the lab's step split (whatever the ZMP's shape)
        schedule = KdistSchedule.lab_split(kdist, self.double_support_s, LAB_ZMP_MOVE_S)
        return kdist_per_joint(self.pattern.timeline.phase(self._tick(time_s)), schedule)

    def planned_motion(self, time_s: float) -> Any:
        """The pattern at this tick (controller.PlannedMotion): the joints' planned increments,
        the planned CoM acceleration and the planned ZMP's split between the feet."""
        from controller import PlannedMotion

        tables = self._planned_tables
        tick = self._tick(time_s)
        return PlannedMotion(
            tables.increment[tick],
            tables.velocity_increment[tick],
            self.pattern.com_acceleration_mps2[tick],
            float(tables.split[tick]),
        )

    @functools.cached_property
    def _planned_tables(self) -> PlannedTables:
        return PlannedTables.of(self.pattern)

    # --- after a run -----------------------------------------------------------------------
    @property
    def walk_ticks(self) -> tuple[int, int]:
        """The walk on the pattern's grid: first double support to the end of the final one."""
        segments = self.pattern.timeline.segments
        return segments[1].start_tick, segments[-1].start_tick

    def metrics(self, run: RunData) -> dict[str, Any]:
        kinematics = WalkingKinematics.of(run, self)
        start, end = (t * self.pattern.dt_s for t in self.walk_ticks)
        stopped_at = stopped_at_s(run)
        until = end if stopped_at is None else min(end, stopped_at)
        # the controller's walk: after a safety stop the loop only holds the robot
        walking = (kinematics.time_s >= start) & (kinematics.time_s < until)
        error = kinematics.zmp_m - kinematics.desired_zmp_m
        fell_at = kinematics.fall_time_s()
        metrics: dict[str, Any] = {
            "zmp_rms_error_m": rms(np.linalg.norm(error, axis=1)[walking]),
            "zmp_max_error_m": largest(np.linalg.norm(error, axis=1)[walking]),
            "zmp_rms_error_lateral_m": rms(error[walking, 1]),
            "zmp_max_error_lateral_m": largest(np.abs(error[walking, 1])),
            "zmp_rms_error_sagittal_m": rms(error[walking, 0]),
            "zmp_max_error_sagittal_m": largest(np.abs(error[walking, 0])),
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

    def derived_series(self, run: RunData) -> DerivedSeries:
        """kinematics.csv (hil/output/series.py): from the walk's start, every log row's ZMP,
        the pattern's ZMP, CoM, pelvis tilt, support margin and the feet's vertical forces, as
        `metrics` sees them."""
        k = WalkingKinematics.of(run, self)
        return kinematics_series(
            run.columns["tick"][k.rows], run.time_s[k.rows], k.zmp_m, k.desired_zmp_m,
            k.com_m, k.tilt_rad, k.margin_m, k.vertical_n,
        )  # fmt: skip

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
class PlannedTables:
    """A pattern's planned motion per tick (n ticks): the joints' increments theta(k) -
    theta(k-1) (n, 12) and their velocity increments (n, 12) [rad/s], and where the planned
    ZMP lies between the feet's ZMP points, 0 at the left's, 1 at the right's (n,): (7)'s mu of
    the plan (at the end of each double support the ZMP is on the next stance foot's point,
    so mu meets the single support's 0 or 1 without a jump)."""

    increment: np.ndarray
    velocity_increment: np.ndarray
    split: np.ndarray

    @classmethod
    def of(cls, pattern: Any) -> PlannedTables:
        from controller.walking.dyros_jet_figures import SOLE_CENTRE_AHEAD_OF_ANKLE_M

        angles = pattern.joint_angles_rad
        increment = np.diff(angles, axis=0, prepend=angles[:1])
        velocity = increment / pattern.dt_s
        velocity_increment = np.diff(velocity, axis=0, prepend=velocity[:1])
        inward = pattern.params.zmp.inward_offset_m
        points = pattern.foot_position_m[:, :, :2].copy()
        yaw = pattern.foot_yaw_rad
        for side, sign in ((0, 1.0), (1, -1.0)):  # each foot's ZMP point (zmp_reference.py)
            along, across = SOLE_CENTRE_AHEAD_OF_ANKLE_M, -sign * inward
            points[:, side, 0] += np.cos(yaw[:, side]) * along - np.sin(yaw[:, side]) * across
            points[:, side, 1] += np.sin(yaw[:, side]) * along + np.cos(yaw[:, side]) * across
        span = points[:, 1] - points[:, 0]
        offset = pattern.zmp_reference_m - points[:, 0]
        split = np.clip(np.sum(offset * span, axis=1) / np.sum(span * span, axis=1), 0.0, 1.0)
        for array in (increment, velocity_increment, split):
            array.setflags(write=False)
        return cls(increment, velocity_increment, split)


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
