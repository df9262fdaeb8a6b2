"""What an experiment is: a reference for every joint, a world, metrics, a plot, the paper's claims.

An experiment module (contact.py, impact.py, ...) defines one `Experiment`:
    reference       the desired link angle of every joint over time (`reference_table` samples
                    it once per run on the loop's grid: no per-tick work)
    reference_feedback  only for an experiment whose reference follows what the robot
                    measures (the walks: the lab's CoM feedback on the pelvis): a
                    `ReferenceFeedback` made for one run, which the loop asks each tick for
                    the reference from the planned one and that tick's measured link angles.
                    None (the default): the reference is the table, a function of time alone
    world           what the world does to the robot: an obstacle, pushes. On hardware the user
                    makes it happen; the emulator builds it from the same figures
    phase           a named phase of the experiment at a time; on a humanoid, the support state
                    (`support`) and a Kdist schedule (`kdist_at`) follow from it
    reaction_policy how its robot does the supervisor's reactions (hil.vocabulary
                    `ReactionPolicy`): the default, as configured; the humanoid's,
                    hil/experiments/legs.py `on_feet`
    goal_offsets    only for an open-loop experiment (identification): the goal itself, as
                    offsets from the goal in force when the experiment starts; the loop sends
                    them instead of stepping the controller (the supervisor still limits them)
    parameters      what meta.json records of the experiment beyond its name
    metrics         the figures it reports, over all joints, from a run's log
    derived_series  per-tick series it derives from the log for plots and analysis (the
                    humanoid's ZMP, CoM and pelvis tilt: kinematics.csv), written beside the
                    log after the run (hil/output/series.py); None (the default): none
    marks           what its plots mark (the obstacle, the pushes, the first contact)
    comparison      its figure across controllers, the paper's claims it checks (`relations`)
                    and the metrics columns of the report table
Adding an experiment is one new module plus a line in its robot's profile
(hil/robots/<name>/__init__.py `experiments`).
"""

from __future__ import annotations

import abc
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hil.config import Config
from hil.output.plots import ComparisonRun, WorldMarks
from hil.output.plots import Push as PushMark
from hil.output.records import RunEntry
from hil.output.report import Column, Relation
from hil.output.rundir import RunData
from hil.output.series import DerivedSeries
from hil.vocabulary import ControllerChoice, ReactionPolicy


@dataclass(frozen=True)
class Ramp:
    """Cosine ramp of the reference from `start_rad` to `end_rad` between two times."""

    start_s: float
    duration_s: float
    start_rad: float
    end_rad: float

    def value(self, time_s: float) -> float:
        if time_s <= self.start_s:
            return self.start_rad
        if time_s >= self.start_s + self.duration_s:
            return self.end_rad
        phase = (time_s - self.start_s) / self.duration_s
        return self.start_rad + (self.end_rad - self.start_rad) * 0.5 * (
            1 - math.cos(math.pi * phase)
        )


@dataclass(frozen=True)
class Push:
    """A push on the load of `joint`, perpendicular to its link; negative pushes the load down."""

    start_s: float
    duration_s: float
    force_n: float
    joint: int = 0


@dataclass(frozen=True)
class Obstacle:
    """A block with a force sensor: the link angle at which the load touches it."""

    contact_angle_rad: float


@dataclass(frozen=True)
class PelvisPush:
    """A push on the humanoid's pelvis: a constant force [N] (world frame) for a while."""

    start_s: float
    duration_s: float
    force_n: tuple[float, float, float]


@dataclass(frozen=True)
class FloorObject:
    """A rigid box lying on the floor under the humanoid's path (the walking plan does not know
    it): the centre of its footprint (x, y) [m] in the plan's frame (the frame the robot starts
    in: the middle of its soles at the origin) and its full size (x, y, height) [m]."""

    centre_m: tuple[float, float]
    size_m: tuple[float, float, float]

    @property
    def height_m(self) -> float:
        return self.size_m[2]


@dataclass(frozen=True)
class ToolPush:
    """A push at a fixed-base robot's tool ([model] tool_link, tool_point_m): a constant force
    [N] (world frame: the URDF's root frame) for a while."""

    start_s: float
    duration_s: float
    force_n: tuple[float, float, float]


@dataclass(frozen=True)
class Block:
    """A rigid box fixed in the world (the URDF's root frame) that a fixed-base robot's tool may
    touch, on a force sensor (`[force_sensor]`): its centre and full size [m], axis-aligned."""

    centre_m: tuple[float, float, float]
    size_m: tuple[float, float, float]


@dataclass(frozen=True)
class World:
    """What the world does during the experiment (experiment time, from its start)."""

    pushes: tuple[Push, ...] = ()
    obstacle: Obstacle | None = None
    pelvis_pushes: tuple[PelvisPush, ...] = ()
    floor_objects: tuple[FloorObject, ...] = ()
    tool_pushes: tuple[ToolPush, ...] = ()
    block: Block | None = None
    # a humanoid hung by its pelvis from a gantry, its feet clear of the floor (the legs'
    # identification, hil/experiments/suspended.py): the emulator hangs it so
    suspended: bool = False


class ReferenceFeedback(abc.ABC):
    """The reference of one run, corrected tick by tick from what the robot measures.

    Stateful (it may integrate), made fresh for each run by `Experiment.reference_feedback`;
    the loop calls `reference` once per tick on which the controller steps, in tick order."""

    @abc.abstractmethod
    def reference(
        self,
        time_s: float,
        planned_rad: np.ndarray,
        link_angle_rad: np.ndarray,
        motor_angle_rad: np.ndarray | None = None,
    ) -> np.ndarray:
        """The desired link angles [rad] at experiment time `time_s` from the planned ones
        (the run's reference table) and this tick's measured link angles (every joint), and
        its motor angles where the loop has them."""

    @abc.abstractmethod
    def describe(self) -> str:
        """What corrects the reference, in a line (for the run's events and summary)."""


class Experiment(abc.ABC):
    """One experiment; see the module docstring. Subclasses are frozen dataclasses."""

    name: str
    title: str
    duration_s: float
    world: World

    # --- the reference ---------------------------------------------------------------------
    @abc.abstractmethod
    def reference(self, time_s: float) -> float | np.ndarray:
        """The desired link angle(s) [rad] at experiment time `time_s`: one value for every
        joint, or one per joint."""

    def reference_table(self, period_s: float, ticks: int, n_joints: int) -> np.ndarray:
        """The reference on the loop's grid: ticks x n_joints [rad], row k at k * period_s."""
        table = np.empty((ticks, n_joints))
        for k in range(ticks):
            table[k] = self.reference(k * period_s)
        return table

    def reference_range(self, n_joints: int) -> tuple[np.ndarray, np.ndarray]:
        """Per joint, the lowest and highest reference (to check against the joints' limits)."""
        ticks = max(2, int(round(self.duration_s / 0.005)) + 1)
        table = self.reference_table(self.duration_s / (ticks - 1), ticks, n_joints)
        return table.min(axis=0), table.max(axis=0)

    def reference_feedback(
        self, config: Config, choice: ControllerChoice
    ) -> ReferenceFeedback | None:
        """A fresh `ReferenceFeedback` for one run of `choice` on `config`'s robot, or None (the
        default): the reference is the table alone."""
        return None

    def phase(self, time_s: float) -> str:
        """The experiment's phase at `time_s` (a single phase unless an experiment has more)."""
        return self.name

    def support(self, time_s: float) -> object | None:
        """Which feet carry the robot at `time_s` (a `controller.humanoid.SupportState`), or
        None for a robot without feet."""
        return None

    def kdist_at(self, time_s: float, kdist: float) -> np.ndarray | None:
        """The DOB gain per joint at `time_s` when the experiment schedules it (the controller
        ramps between values), or None: the run's constant `kdist`."""
        return None

    def reaction_policy(self) -> ReactionPolicy:
        """How this experiment's robot does the configured reactions, fresh for one run
        (hil.vocabulary `ReactionPolicy`); the default does each as configured."""
        return ReactionPolicy()

    def planned_motion(self, time_s: float) -> Any:
        """What the experiment's plan says at `time_s` beyond the reference (a
        `controller.PlannedMotion`: the reference's planned increments, the planned CoM
        acceleration and ZMP split), or None: no plan (the controller sees the reference
        alone)."""
        return None

    # --- open-loop goals ---------------------------------------------------------------------
    @property
    def open_loop(self) -> bool:
        """True when the experiment sends its own goals (`goal_offsets`), no controller."""
        return False

    def goal_offsets(self, period_s: float, ticks: int, n_joints: int) -> np.ndarray | None:
        """An open-loop experiment's goals on the loop's grid: ticks x n_joints offsets [rad]
        from the goal in force when its timeline starts, row k at experiment time k * period_s.
        None (closed loop, the default): the controller proposes the goals along the reference.
        """
        return None

    def parameters(self) -> dict[str, Any]:
        """What a run's meta.json records of this experiment beyond its name (JSON data)."""
        return {}

    # --- after a run -----------------------------------------------------------------------
    @abc.abstractmethod
    def metrics(self, run: RunData) -> dict[str, Any]:
        """The figures this experiment reports, from a run's log (over all joints)."""

    def derived_series(self, run: RunData) -> DerivedSeries | None:
        """Per-tick series derived from a finished run's log (its summary.json written), from
        the same computation as `metrics`: `hil run` writes them as `file_name` into the run
        directory (hil/output/series.py). None (the default): this experiment has none.

        Example, a plug-in's tracking error per tick (errors.csv)::

            def derived_series(self, run):
                error = run.signal("link_angle_rad") - run.signal("reference_rad")
                columns = {"tick": run.columns["tick"], "time_s": run.time_s, "error_rad": error}
                return DerivedSeries("errors.csv", columns)
        """
        return None

    def marks(self, run: RunData) -> WorldMarks:
        """What a plot of this run marks; times in loop time (after any re-homing)."""
        start = run.experiment_start_s
        obstacle = self.world.obstacle
        return WorldMarks(
            pushes=tuple(
                PushMark(p.start_s + start, p.duration_s, p.force_n) for p in self.world.pushes
            ),
            obstacle_angle_rad=obstacle.contact_angle_rad if obstacle else None,
            title=self.title,
            experiment=self.name,
        )

    # --- across controllers ----------------------------------------------------------------
    def relations(self, entries: Sequence[RunEntry]) -> list[Relation]:
        """The paper's claims about this experiment, checked against the runs' metrics."""
        return []

    def comparison_figure(
        self, runs: Sequence[ComparisonRun], path: Path, setup: str
    ) -> Path | None:
        """The experiment's figure across controllers (None: it has none)."""
        return None

    @property
    def figure_name(self) -> str:
        return f"{self.name}.png"

    @property
    def report_columns(self) -> tuple[Column, ...]:
        """The metrics shown in the report table, in order, with their headers and formats."""
        return ()


@dataclass(frozen=True)
class TestbedExperiment(Experiment, abc.ABC):
    """An experiment of the 1-DoF testbed: the same reference for every joint, made of ramps
    from `initial_angle_rad`."""

    __test__ = False  # not a pytest test class

    name: str
    title: str
    duration_s: float
    initial_angle_rad: float
    ramps: tuple[Ramp, ...] = ()
    world: World = World()

    def reference(self, time_s: float) -> float:
        value = self.initial_angle_rad
        for ramp in self.ramps:
            if time_s >= ramp.start_s:
                value = ramp.value(time_s)
        return value

    def reference_range(self, n_joints: int) -> tuple[np.ndarray, np.ndarray]:
        ends = [self.initial_angle_rad, *(r.end_rad for r in self.ramps)]
        return np.full(n_joints, min(ends)), np.full(n_joints, max(ends))
