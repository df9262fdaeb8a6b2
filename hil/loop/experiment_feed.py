"""What the experiment hands the loop, tick by tick: the phases of the run (`timeline`, with the
re-homing planned on tick 0), the link reference (re-homing first, then the experiment's),
computed ahead into a ring of REFERENCE_AHEAD_TICKS rows so that a run's memory does not grow
with its planned duration; an open-loop experiment's goal offsets, checked before anything
moves; the LQR's contact on the experiment's grid; and the experiment's correction of its
reference from the measured sample (`ReferenceFeedback`)."""

from __future__ import annotations

import math

import numpy as np

from hil.config import Config
from hil.controllers.robot_model import RobotModel
from hil.experiments import Experiment
from hil.experiments.base import ReferenceFeedback
from hil.loop.homing import HomingPlan, plan_homing
from hil.loop.timeline import Timeline
from hil.safety import ReferenceOutsideLimits
from hil.vocabulary import ControllerChoice

# The reference is computed this many ticks ahead (60 s: all of a usual experiment at tick 0),
# then one tick at a time in a ring of this many rows: a run's memory does not grow with its
# planned duration, and no later tick computes more than the rows the clock skipped.
REFERENCE_AHEAD_TICKS = 12_000


class ExperimentFeed:
    """The experiment's timeline, reference ring, open-loop goals and LQR contacts for a run."""

    def __init__(
        self,
        config: Config,
        experiment: Experiment,
        choice: ControllerChoice,
        robot: RobotModel,
        period_s: float,
        duration_s: float,
    ) -> None:
        self.experiment = experiment
        self.robot = robot
        self.period = period_s
        self.n = len(config.joints)
        self.timeline = Timeline.plan(period_s, config.loop.stop_cycles, duration_s)
        self.lqr_contacts = self._lqr_contact_table(duration_s)
        self.open_loop = self._open_loop_offsets(config.safety.max_goal_rate_rad_s)
        self.feedback: ReferenceFeedback | None = (
            None if self.open_loop is not None else experiment.reference_feedback(config, choice)
        )
        self.homing: HomingPlan | None = None
        self.references = np.zeros((0, self.n))  # a ring: tick k's row is at k % len
        self._filled = 0  # the first tick whose row is not in the ring yet
        self._goal_base: np.ndarray | None = None  # an open-loop experiment's goals start here

    @property
    def start_reference(self) -> np.ndarray:
        return np.broadcast_to(self.experiment.reference(0.0), (self.n,))

    # --- tick 0 ------------------------------------------------------------------------------
    def plan_start(self, link_angle_rad: np.ndarray) -> HomingPlan | None:
        """Torque is on: the re-homing if the link starts away from the experiment's start, and
        the reference ring filled ahead."""
        self.homing = plan_homing(link_angle_rad, self.start_reference)
        if self.homing is not None:
            self.timeline = self.timeline.with_homing(self.homing.ticks(self.period))
        ahead = min(self.timeline.end, REFERENCE_AHEAD_TICKS)
        self.references = np.empty((ahead, self.n))
        self._filled = 0
        self.fill_ahead(-1)
        return self.homing

    # --- the reference -----------------------------------------------------------------------
    def reference_row(self, k: int) -> np.ndarray:
        """Tick k's row of the reference (the ring filled first if the clock skipped more ticks
        than it holds)."""
        if k >= self._filled:
            self.fill_ahead(k - 1)
        return self.references[k % len(self.references)]

    def fill_ahead(self, k: int) -> None:
        """Fill the ring up to tick k + its length - 1: the slots of ticks up to k, whose rows
        are written (tick k's row is kept for the next tick's log: not overwritten)."""
        ring = self.references
        stop = min(self.timeline.end, k + len(ring))
        while self._filled < stop:
            tick = self._filled
            ring[tick % len(ring)] = self._reference_at(tick)
            self._filled = tick + 1

    def _reference_at(self, k: int) -> float | np.ndarray:
        """The link reference of tick k (re-homing first, then the experiment's)."""
        timeline = self.timeline
        if self.homing is not None and k < timeline.hold_ticks + timeline.homing_ticks:
            return self.homing.reference((k - timeline.hold_ticks) * self.period)
        return self.experiment.reference(timeline.experiment_time_s(k))

    # --- open-loop goals ---------------------------------------------------------------------
    def _open_loop_offsets(self, max_goal_rate_rad_s: float) -> np.ndarray | None:
        """An open-loop experiment's goal offsets (None: closed loop), refused before anything
        moves if they would move the goal faster than the supervisor allows (it would rewrite
        the goals the experiment is about)."""
        experiment = self.experiment
        offsets = experiment.goal_offsets(self.period, self.timeline.experiment_ticks, self.n)
        if offsets is None:
            return None
        offsets = np.asarray(offsets, dtype=float)
        if offsets.shape != (self.timeline.experiment_ticks, self.n) or not np.all(
            np.isfinite(offsets)
        ):
            raise ValueError(f"{experiment.name}: goal offsets not finite ticks x joints")
        steps = np.abs(np.diff(offsets, axis=0, prepend=offsets[:1]))
        rate = float(steps.max(initial=0.0)) / self.period
        if rate > max_goal_rate_rad_s * (1 + 1e-9):
            raise ReferenceOutsideLimits(
                f"{experiment.name} moves the goal at up to {rate:.3f} rad/s, above "
                f"[safety] max_goal_rate_rad_s = {max_goal_rate_rad_s:g}: the supervisor would "
                "rewrite it; nothing was sent"
            )
        return offsets

    def open_loop_goal(self, k: int, goal_in_force: np.ndarray) -> np.ndarray:
        """The goal in force when the experiment began plus its offset for tick k."""
        assert self.open_loop is not None
        if self._goal_base is None:
            self._goal_base = goal_in_force.copy()
        index = min(k - self.timeline.homing_ticks, len(self.open_loop) - 1)
        return self._goal_base + self.open_loop[index]

    # --- the LQR's contact -------------------------------------------------------------------
    def _lqr_contact_table(self, duration_s: float) -> list[object]:
        """The LQR's contact on the experiment's own grid: the paper's switch at mid double
        support needs the whole phase ahead (hil/controllers/robot_model.py). A robot whose Sm
        is constant has no contact: one entry."""
        experiment = self.experiment
        if not self.robot.rescheduled:
            return self.robot.lqr_contacts([experiment.support(0.0)])
        ticks = max(1, math.ceil(duration_s / self.period - 1e-9))
        return self.robot.lqr_contacts([experiment.support(i * self.period) for i in range(ticks)])

    def lqr_contact(self, k: int) -> object:
        """The LQR's contact at tick k (the experiment's grid, held at its ends)."""
        index = round(self.timeline.experiment_time_s(k) / self.period)
        return self.lqr_contacts[min(max(index, 0), len(self.lqr_contacts) - 1)]
