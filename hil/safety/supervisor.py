"""The safety supervisor: between the controller and the bus, every tick.

What it does each tick, in this order:
1. run the watches on the sample (`observe`; hil/safety/watches.py and link_watches.py say
   what each watches);
2. when a watch trips, latch the safe state configured for that cause (`[safety] on_<cause>`)
   and record it with the joint, the tick, the time and the figures (`events`); each cause is
   reported once per joint (once per fault code for actuator faults). The experiment's
   `ReactionPolicy` (hil/vocabulary.py, `set_reaction_policy`) may do a configured
   reaction as another on its robot (the humanoid: `back_off` as `finish_step`); the event
   names both;
3. shape the command (`command`): in normal running, reject a non-finite goal
   (`command_invalid`), clip each goal to its joint's position limits and to the goal rate
   limit (a goal clipped at a limit on more than `goal_saturation_fraction` of the last
   `goal_saturation_window_ticks` ticks is `goal_saturated`: the controller is fighting the
   limits); in a safe state, replace it:
       finish_step let the controller's goals through as in normal running (the controller goes
                   on along the experiment's reference) until the policy's rest condition holds
                   (a walk: both feet carry the robot) or its time is up, then hold
       hold        keep the motor where it was when the state was entered
       back_off    move the goal `current_guard_backoff_rad` away from the direction the motor
                   was pushing (sign of its current: relieves a load or a contact), then hold
       torque_off  torque off on every joint (the loop calls `bus.disable()`), no more goals
   A later, more severe cause escalates (finish_step -> hold -> back_off -> torque_off), never
   the reverse.
Settings that are legal but dangerous are a cause too (`check_settings`, at the start): a DOB
gain beyond `max_kdist` (`gain_out_of_range`).
Recovery is never automatic: a latched safe state lasts until the run ends; clearing an
actuator's fault takes an explicit `hil reboot` or `hil run --reboot-first` (see
hil/loop/homing.py for the slow re-homing that follows).
"""

from __future__ import annotations

import collections
import enum
from collections.abc import Sequence
from typing import Any

import numpy as np

from drivers.joint_bus import JointDevices, JointSample
from hil.config import SafetySection
from hil.safety.overload import H54_200_S500_R, GuardRule, OverloadProtection
from hil.safety.watch_set import Watches
from hil.safety.watches import WatchContext
from hil.vocabulary import (
    NoticeKind,
    Reaction,
    ReactionPolicy,
    SafetyCause,
    SafetyEvent,
    SafetyNotice,
)

MAX_NOTICES_PER_KIND = 20  # per joint and kind; later ones are only counted (summary.json)


class ReferenceOutsideLimits(ValueError):
    """An experiment's reference leaves a joint's range: refused before any port is opened."""


class SafeState(enum.IntEnum):
    """The supervisor's state, ordered by severity."""

    RUN = 0
    FINISH_STEP = 1  # the controller still steps, until the experiment's rest
    HOLD = 2
    BACK_OFF = 3
    TORQUE_OFF = 4

    @classmethod
    def of(cls, reaction: Reaction) -> SafeState:
        return {
            Reaction.FINISH_STEP: cls.FINISH_STEP,
            Reaction.HOLD: cls.HOLD,
            Reaction.BACK_OFF: cls.BACK_OFF,
            Reaction.TORQUE_OFF: cls.TORQUE_OFF,
        }[reaction]


class Supervisor:
    """See the module docstring. One instance per run.

    joint_names, devices: one entry per joint; min/max_angle_rad: the joints' position limits;
    stiffness_nm_per_rad: per joint (the deflection message gives the gear torque);
    protections: each joint's actuator model's overload protection, which the current guard's
    rule derives from (hil/safety/overload.py; default: the H54-200-S500-R's on every joint).
    """

    def __init__(
        self,
        safety: SafetySection,
        joint_names: Sequence[str],
        devices: Sequence[JointDevices],
        min_angle_rad: np.ndarray,
        max_angle_rad: np.ndarray,
        period_s: float,
        stiffness_nm_per_rad: np.ndarray,
        protections: Sequence[OverloadProtection] | None = None,
    ) -> None:
        n = len(joint_names)
        if n == 0 or len(devices) != n:
            raise ValueError("the supervisor needs one device entry per joint, and a joint")
        if not period_s > 0:
            raise ValueError(f"period_s must be > 0, got {period_s}")
        self.safety = safety
        self.names = tuple(joint_names)
        self.min_goal = np.asarray(min_angle_rad, dtype=float).copy()
        self.max_goal = np.asarray(max_angle_rad, dtype=float).copy()
        if not np.all(self.min_goal < self.max_goal):
            raise ValueError("every joint needs min_angle_rad < max_angle_rad")
        self.max_goal_step = np.full(n, safety.max_goal_rate_rad_s * period_s)
        self._period_s = period_s
        context = WatchContext(
            safety, tuple(devices), period_s, np.asarray(stiffness_nm_per_rad, dtype=float)
        )
        if protections is None:
            protections = (H54_200_S500_R,) * n
        if len(protections) != n:
            raise ValueError("the supervisor needs one overload protection per joint")
        self.watches = Watches.default(context, GuardRule.of(safety, protections))
        self.policy = ReactionPolicy()
        self._finish_ticks_left = 0
        self.state = SafeState.RUN
        self.events: list[SafetyEvent] = []
        self.notices: list[SafetyNotice] = []
        self._reported: set[tuple[Any, ...]] = set()
        self._hold_goal: np.ndarray | None = None
        self._hold_state = SafeState.RUN
        self._last_goal: np.ndarray | None = None
        self._tick = 0
        self._time_s = 0.0
        self._notice_counts: collections.Counter[tuple[NoticeKind, str | None]] = (
            collections.Counter()
        )
        self._clipped_total = np.zeros(n, dtype=int)
        self._rate_limited_total = np.zeros(n, dtype=int)
        window = safety.goal_saturation_window_ticks
        self._clipped_recent = np.zeros((window, n), dtype=bool)
        self._clipped_recent_count = np.zeros(n, dtype=int)
        self._saturation_trip = np.ceil(safety.goal_saturation_fraction * window)

    # --- lifecycle -------------------------------------------------------------------------
    def torque_enabled(self, goal_rad: np.ndarray) -> None:
        """The loop turned torque on with this goal (the present motor angle)."""
        self.watches.actuator.expect_torque = True
        self._last_goal = np.array(goal_rad, dtype=float)

    def set_reaction_policy(self, policy: ReactionPolicy) -> None:
        """How this run's robot does the reactions (the experiment's; before the first tick)."""
        self.policy = policy

    def torque_disabled(self) -> None:
        self.watches.actuator.expect_torque = False

    def set_current_limits(self, limits_a: np.ndarray) -> None:
        """The actuators' current caps [A] the overload guard compares against (the devices
        report them at open). NaN: unknown, the guard cannot act on that joint."""
        limit = np.broadcast_to(np.asarray(limits_a, dtype=float), self.min_goal.shape).copy()
        if np.any(limit <= 0):
            raise ValueError(f"current limits must be > 0 A, got {limit}")
        self.watches.current.current_limit_a = limit

    @property
    def current_limits_a(self) -> np.ndarray:
        return self.watches.current.current_limit_a

    @property
    def safe(self) -> bool:
        """True once any cause has latched a safe state."""
        return self.state != SafeState.RUN

    @property
    def controller_steps(self) -> bool:
        """The controller's goals are wanted: normal running, or a `finish_step` on its way."""
        return self.state <= SafeState.FINISH_STEP

    @property
    def first_trip(self) -> SafetyEvent | None:
        return self.events[0] if self.events else None

    @property
    def overruns(self) -> int:
        return self.watches.overrun.total

    def counters(self) -> dict[str, Any]:
        """Totals for summary.json: what was tolerated or shaped, per joint."""

        def per_joint(counts: np.ndarray) -> dict[str, int]:
            return dict(zip(self.names, counts.tolist(), strict=True))

        return {
            "motor_invalid_ticks": per_joint(self.watches.bus.bad_total),
            "link_invalid_ticks": per_joint(self.watches.link_stale.bad_total),
            "goals_clipped_at_limit": per_joint(self._clipped_total),
            "goals_rate_limited": per_joint(self._rate_limited_total),
            "overruns": self.overruns,
            "current_guard": self._guard_record(),
        }

    def _guard_record(self) -> dict[str, Any]:
        """The guard's rule and how far each joint's timer ran (summary.json)."""
        if not self.safety.current_guard:
            return {"on": False}
        guard = self.watches.current
        peak = np.round(guard.peak_timer_s, 6).tolist()
        return {
            "on": True,
            **guard.rule.record(self.names),
            "peak_timer_s": dict(zip(self.names, peak, strict=True)),
        }

    # --- 1. watch --------------------------------------------------------------------------
    def observe(self, tick: int, time_s: float, sample: JointSample) -> list[SafetyEvent]:
        """Run every watch on this tick's sample; returns the events it raised."""
        self._tick, self._time_s = tick, time_s
        before = len(self.events)
        for watch in self.watches.in_order:
            watch.observe(sample, self)
        rest = self.policy.rest
        if rest is not None:  # asked every tick: a condition that counts ticks is current
            at_rest = rest.reached(sample)
            if self.state == SafeState.FINISH_STEP:
                self._finish_step(rest.describe(), at_rest)
        return self.events[before:]

    def _finish_step(self, rest: str, at_rest: str | None) -> None:
        """Hold once the rest is reached or the policy's time is up (recorded as an event of
        the cause that started the finish_step)."""
        self._finish_ticks_left -= 1
        if at_rest is None and self._finish_ticks_left > 0:
            return
        if at_rest is not None:
            why = f"the step is finished ({at_rest}): holding"
        else:
            why = f"no rest ({rest}) within {self.policy.within_s:g} s: holding where it is"
        self.state = SafeState.HOLD
        first = next(e for e in self.events if e.action is Reaction.FINISH_STEP)
        self.events.append(
            SafetyEvent(
                self._tick, self._time_s, first.cause, first.joint, Reaction.HOLD, why, "hold"
            )
        )

    def note_overrun(self, tick: int, time_s: float, skipped: int) -> None:
        """The loop missed a deadline this tick; `skipped` grid ticks were lost entirely."""
        self._tick, self._time_s = tick, time_s
        self.watches.overrun.note(tick, skipped, self)

    # --- 2. latch and record (the watches' Reporter) ------------------------------------------
    def trip(
        self, cause: SafetyCause, joint: int | None, message: str, detail: object = None
    ) -> None:
        name = None if joint is None else self.names[joint]
        key = (cause, name, detail)
        if key in self._reported:
            return
        self._reported.add(key)
        configured = self.safety.reaction(cause)
        reaction = self.policy.done_as(configured)
        if reaction is not configured:
            message += f" ({cause.config_key} = {configured}: on this robot done as {reaction})"
        target = SafeState.of(reaction)
        rest = self.policy.rest
        if target is SafeState.FINISH_STEP and rest is None:
            target = SafeState.HOLD  # nothing to finish: hold at once
        if target > self.state:
            if target is SafeState.FINISH_STEP and rest is not None:
                message += f"; until {rest.describe()}"
                self._finish_ticks_left = max(1, round(self.policy.within_s / self._period_s))
            self.state = target
        self.events.append(
            SafetyEvent(
                self._tick, self._time_s, cause, name, reaction, message, self.state.name.lower()
            )
        )

    def notice(self, kind: NoticeKind, joint: int | None, message: str) -> None:
        name = None if joint is None else self.names[joint]
        self._notice_counts[(kind, name)] += 1
        count = self._notice_counts[(kind, name)]
        if count > MAX_NOTICES_PER_KIND:
            return
        if count == MAX_NOTICES_PER_KIND:
            message += f" (further {kind} notices are only counted in summary.json)"
        self.notices.append(SafetyNotice(self._tick, self._time_s, kind, name, message))

    # --- 3. shape the command ----------------------------------------------------------------
    def command(self, controller_goal: np.ndarray | None, sample: JointSample) -> np.ndarray | None:
        """The goal to send this tick, or None to send nothing (torque off, or nothing known).

        Call after `observe` on the same tick. Whatever is returned lies within every joint's
        [min_angle_rad, max_angle_rad].
        """
        if self.state == SafeState.TORQUE_OFF:
            return None
        if self.state <= SafeState.FINISH_STEP:
            goal = controller_goal if controller_goal is not None else self._last_goal
            if goal is None:
                return None
            goal = np.asarray(goal, dtype=float)
            if (
                goal.shape != self.min_goal.shape
                or np.count_nonzero(np.isfinite(goal)) != goal.size
            ):
                self.trip(
                    SafetyCause.COMMAND_INVALID,
                    None,
                    f"the controller proposed {goal.tolist()} for {len(self.names)} joint(s): "
                    "not one finite goal per joint",
                )
                return self.command(None, sample)
            goal = self._limit(goal)
        else:
            if self._hold_goal is None or self._hold_state != self.state:
                self._hold_goal = self._safe_goal(sample)
                self._hold_state = self.state
            if self._hold_goal is None:
                return None
            goal = self._hold_goal
        self._last_goal = goal
        self.watches.link_noise.note_goal(goal)
        return goal.copy()

    def _limit(self, goal: np.ndarray) -> np.ndarray:
        clipped = goal.clip(self.min_goal, self.max_goal)  # (np.clip's own method)
        at_limit = clipped != goal
        self._watch_saturation(at_limit)
        if np.count_nonzero(at_limit):
            self._clipped_total += at_limit
            for i in np.flatnonzero(at_limit):
                self.notice(
                    NoticeKind.GOAL_LIMITED,
                    int(i),
                    f"goal {float(goal[i]):+.4f} rad clipped to joint {self.names[i]!r}'s "
                    f"limits [{self.min_goal[i]:+.3f}, {self.max_goal[i]:+.3f}] rad",
                )
        if self._last_goal is None:
            return clipped
        low = self._last_goal - self.max_goal_step
        high = self._last_goal + self.max_goal_step
        limited = clipped.clip(low, high)
        self._rate_limited_total += limited != clipped
        # the last goal is inside the limits, so the rate-limited goal is too
        return limited

    def _watch_saturation(self, at_limit: np.ndarray) -> None:
        window = self._clipped_recent.shape[0]
        recent = self._clipped_recent[self._tick % window]
        self._clipped_recent_count += at_limit
        self._clipped_recent_count -= recent
        recent[:] = at_limit
        saturated = self._clipped_recent_count >= self._saturation_trip
        if not np.count_nonzero(saturated):
            return
        for i in np.flatnonzero(saturated):
            self.trip(
                SafetyCause.GOAL_SATURATED,
                int(i),
                f"the goal was clipped at joint {self.names[i]!r}'s position limits on "
                f"{self._clipped_recent_count[i]} of the last {window} ticks: the controller "
                "is driving against the limits",
            )

    def check_settings(self, kdist: np.ndarray | float) -> None:
        """Settings that are legal but outside what the analysis covers (`max_kdist`)."""
        gain = np.broadcast_to(np.asarray(kdist, dtype=float), self.min_goal.shape)
        limit = self.safety.max_kdist
        for i in np.flatnonzero(gain > limit):
            self.trip(
                SafetyCause.GAIN_OUT_OF_RANGE,
                int(i),
                f"Kdist {gain[i]:g} is beyond max_kdist = {limit:g} (the paper's largest gain, "
                "and the edge of the closed-loop analysis): not run; raise [safety] max_kdist "
                "to run it knowingly",
            )

    def _safe_goal(self, sample: JointSample) -> np.ndarray | None:
        """Where to hold: the motor's present angle (the last goal where it is unknown);
        for back_off, moved away from the direction the motor current pushes."""
        n = len(self.names)
        last = self._last_goal if self._last_goal is not None else np.full(n, np.nan)
        base = np.where(sample.motor_valid, sample.motor_angle_rad, last)
        base = np.where(np.isfinite(base), base, last)
        if not np.isfinite(base).all():
            return None
        if self.state == SafeState.BACK_OFF:
            current = np.where(sample.motor_valid, sample.motor_current_a, 0.0)
            push = np.sign(np.nan_to_num(current))
            base = base - push * self.safety.current_guard_backoff_rad
        return np.clip(base, self.min_goal, self.max_goal)

    def check_reference(self, reference_min: np.ndarray, reference_max: np.ndarray) -> None:
        """Refuse an experiment whose reference leaves a joint's limits (before anything moves)."""
        low = np.asarray(reference_min, dtype=float)
        high = np.asarray(reference_max, dtype=float)
        if not (np.isfinite(low).all() and np.isfinite(high).all()):
            raise ReferenceOutsideLimits(
                f"the reference spans [{low.tolist()}, {high.tolist()}] rad: not finite"
            )
        for i, name in enumerate(self.names):
            lo = float(np.broadcast_to(low, self.min_goal.shape)[i])
            hi = float(np.broadcast_to(high, self.min_goal.shape)[i])
            if lo < self.min_goal[i] or hi > self.max_goal[i]:
                raise ReferenceOutsideLimits(
                    f"the reference spans [{lo:+.3f}, {hi:+.3f}] rad, beyond joint {name!r}'s "
                    f"limits [{self.min_goal[i]:+.3f}, {self.max_goal[i]:+.3f}] rad: nothing was "
                    "sent; shorten the trajectory or widen min_angle_rad / max_angle_rad in the "
                    "configuration"
                )
