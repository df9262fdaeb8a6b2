"""What the experiment hands the loop, tick by tick (a mixin of `hil.loop.runner.Loop`): the
link reference (re-homing first, then the experiment's), computed ahead into a ring of
REFERENCE_AHEAD_TICKS rows so that a run's memory does not grow with its planned duration; an
open-loop experiment's goal offsets, checked before anything moves; and what the phase sets -
the support state (the gravity compensator), the LQR's contact (Sm and its gain, requested
ahead), a walk's planned motion and a Kdist schedule."""

from __future__ import annotations

import math

import numpy as np

from hil.experiments.base import ReferenceFeedback
from hil.safety import ReferenceOutsideLimits


class ExperimentFeed:
    """The reference ring, the open-loop goals and the phase's settings for `Loop`."""

    def _reference_feedback(self) -> ReferenceFeedback | None:
        """The experiment's correction of its reference from the measured sample, if any."""
        return self.experiment.reference_feedback(self.config, self.request.choice)

    def _open_loop_offsets(self, max_goal_rate_rad_s: float) -> np.ndarray | None:
        """An open-loop experiment's goal offsets (None: closed loop), refused before anything
        moves if they would move the goal faster than the supervisor allows (it would rewrite
        the goals the experiment is about)."""
        offsets = self.experiment.goal_offsets(self.period, self.timeline.experiment_ticks, self.n)
        if offsets is None:
            return None
        offsets = np.asarray(offsets, dtype=float)
        if offsets.shape != (self.timeline.experiment_ticks, self.n) or not np.all(
            np.isfinite(offsets)
        ):
            raise ValueError(f"{self.experiment.name}: goal offsets not finite ticks x joints")
        steps = np.abs(np.diff(offsets, axis=0, prepend=offsets[:1]))
        rate = float(steps.max(initial=0.0)) / self.period
        if rate > max_goal_rate_rad_s * (1 + 1e-9):
            raise ReferenceOutsideLimits(
                f"{self.experiment.name} moves the goal at up to {rate:.3f} rad/s, above "
                f"[safety] max_goal_rate_rad_s = {max_goal_rate_rad_s:g}: the supervisor would "
                "rewrite it; nothing was sent"
            )
        return offsets

    def _reference_ahead(self, k: int) -> None:
        """Fill the ring up to tick k + its length - 1: the slots of ticks up to k, whose rows
        are written (tick k's row is kept for the next tick's log: not overwritten)."""
        ring = self.references
        stop = min(self.timeline.end, k + len(ring))
        while self._reference_filled < stop:
            tick = self._reference_filled
            ring[tick % len(ring)] = self._reference_at(tick)
            self._reference_filled = tick + 1

    def _reference_at(self, k: int) -> float | np.ndarray:
        """The link reference of tick k (re-homing first, then the experiment's)."""
        timeline = self.timeline
        if self.homing is not None and k < timeline.hold_ticks + timeline.homing_ticks:
            return self.homing.reference((k - timeline.hold_ticks) * self.period)
        return self.experiment.reference(timeline.experiment_time_s(k))

    def _schedule(self, k: int, link: np.ndarray) -> None:
        """What the experiment's phase sets: the support state (gravity compensator), the LQR's
        contact (Sm and the gain), and a Kdist schedule (the controller ramps between values)."""
        time_s = self.timeline.experiment_time_s(k)
        support = self.experiment.support(time_s)
        if support != self._support:
            self.robot.set_support(support)
            self._support = support
        if self.scheduler is not None:
            lead = self.scheduler.lead_ticks
            self.scheduler.update(k, link, self._lqr_contact(k), self._lqr_contact(k + lead))
        motion = self.experiment.planned_motion(time_s)  # a walk's plan: GC load, LQR
        self.robot.set_planned_motion(motion)
        self._planned_motion = motion  # the controller's, in its ControlInput
        if self.request.choice.uses_kdist:
            kdist = self.experiment.kdist_at(time_s, self.request.choice.kdist)
            if kdist is not None and (self._kdist is None or np.any(kdist != self._kdist)):
                self.controller.set_kdist(kdist)
                self._kdist = np.array(kdist, dtype=float)

    def _lqr_contact_table(self, duration_s: float) -> list[object]:
        """The LQR's contact on the experiment's own grid: the paper's switch at mid double
        support needs the whole phase ahead (hil/loop/robot_model.py). A robot whose Sm is
        constant has no contact: one entry."""
        if not self.robot.rescheduled:
            return self.robot.lqr_contacts([self.experiment.support(0.0)])
        ticks = max(1, math.ceil(duration_s / self.period - 1e-9))
        return self.robot.lqr_contacts(
            [self.experiment.support(i * self.period) for i in range(ticks)]
        )

    def _lqr_contact(self, k: int) -> object:
        """The LQR's contact at tick k (the experiment's grid, held at its ends)."""
        index = round(self.timeline.experiment_time_s(k) / self.period)
        return self._lqr_contacts[min(max(index, 0), len(self._lqr_contacts) - 1)]

    def _open_loop_goal(self, k: int) -> np.ndarray:
        """The goal in force when the experiment began plus its offset for tick k."""
        assert self._open_loop is not None
        if self._goal_base is None:
            self._goal_base = self._last_goal.copy()
        index = min(k - self.timeline.homing_ticks, len(self._open_loop) - 1)
        return self._goal_base + self._open_loop[index]
