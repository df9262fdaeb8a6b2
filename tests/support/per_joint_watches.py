"""The supervisor's watches as they were before they were vectorised: one joint at a time in
Python. Kept as the reference that tests/hil/test_supervisor_equivalence.py holds the product's
watches (hil/safety/watches.py, link_watches.py) to, event for event and notice for notice.
Not used by the product. `PerJointSupervisor` is the supervisor with these watches and its
command shaping as it was."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from drivers.joint_bus import ActuatorFault, DeviceRole, JointSample
from hil.safety import link_watches as product_link_watches
from hil.safety.overload import GuardRule
from hil.safety.supervisor import SafeState, Supervisor
from hil.safety.watch_set import Watches
from hil.safety.watches import OverrunWatch, Reporter, Watch, WatchContext
from hil.vocabulary import NoticeKind, SafetyCause


class BusErrorWatch(Watch):
    def __init__(self, context: WatchContext) -> None:
        super().__init__(context)
        n = context.n_joints
        self.bad_ticks = np.zeros(n, dtype=int)
        self.bad_total = np.zeros(n, dtype=int)
        self._reason = [""] * n

    def observe(self, sample: JointSample, report: Reporter) -> None:
        limit = self.context.safety.bus_error_ticks
        for i in range(self.context.n_joints):
            actuator = self.context.devices[i].actuator
            if sample.motor_valid[i]:
                if self.bad_ticks[i]:
                    streak = (
                        f"{actuator}: {self.bad_ticks[i]} tick(s) without a valid reply "
                        f"({self._reason[i]}), then it answered again"
                    )
                    if self.bad_ticks[i] < limit:
                        message = f"{streak}: tolerated (bus_error_ticks = {limit})"
                        report.notice(NoticeKind.BUS_GLITCH, i, message)
                    else:
                        message = f"{streak}; the safe state stays latched"
                        report.notice(NoticeKind.BUS_RECOVERED, i, message)
                self.bad_ticks[i] = 0
                continue
            self.bad_ticks[i] += 1
            self.bad_total[i] += 1
            mine = sample.errors_of(i, DeviceRole.ACTUATOR)
            self._reason[i] = "; ".join(f.message for f in mine) or "no valid reply"
            if self.bad_ticks[i] >= limit:
                report.trip(
                    SafetyCause.BUS_ERROR,
                    i,
                    f"{actuator}: {self.bad_ticks[i]} ticks in a row without a valid reply "
                    f"({self._reason[i]})",
                )


class ActuatorFaultWatch(Watch):
    """Reports a fault whether or not the actuator has turned its torque off: an overheating
    warning outside the device's shutdown mask leaves torque on and still counts."""

    def __init__(self, context: WatchContext) -> None:
        super().__init__(context)
        self.expect_torque = False  # set by the supervisor when the loop turns torque on

    def observe(self, sample: JointSample, report: Reporter) -> None:
        for i in range(self.context.n_joints):
            if not sample.motor_valid[i]:
                continue
            actuator = self.context.devices[i].actuator
            flags = int(sample.actuator_fault[i])
            if flags:
                code = int(sample.fault_code[i])
                torque = "on" if sample.torque_enabled[i] else "off"
                report.trip(
                    SafetyCause.HARDWARE_ERROR,
                    i,
                    f"{actuator} reports {ActuatorFault.describe(flags)} (device code "
                    f"0x{code:02X}); torque is {torque}",
                    detail=code,
                )
            elif self.expect_torque and not sample.torque_enabled[i]:
                report.trip(
                    SafetyCause.TORQUE_LOST,
                    i,
                    f"{actuator} reads torque off without a fault (someone else turned torque "
                    "off, or the device restarted)",
                )


class CurrentGuardWatch(Watch):
    """A timer runs up while |current| >= the rule's fraction x the active current limit and
    back down (never below 0) while it is not; it fires at the rule's time
    (hil/safety/overload.py `GuardRule`)."""

    def __init__(self, context: WatchContext, rule: GuardRule) -> None:
        super().__init__(context)
        n = context.n_joints
        self.rule = rule
        self.timer_s = np.zeros(n)
        self.peak_timer_s = np.zeros(n)
        self.current_limit_a = np.full(n, np.nan)

    def observe(self, sample: JointSample, report: Reporter) -> None:
        s = self.context.safety
        if not s.current_guard:
            return
        period = self.context.period_s
        for i in range(self.context.n_joints):
            if not sample.motor_valid[i]:
                continue
            current = abs(float(sample.motor_current_a[i]))
            limit = self.current_limit_a[i]
            near = current >= self.rule.fraction[i] * limit  # False if the limit is NaN
            self.timer_s[i] = max(0.0, self.timer_s[i] + (period if near else -period))
            self.peak_timer_s[i] = max(self.peak_timer_s[i], self.timer_s[i])
            if self.timer_s[i] >= self.rule.time_s[i] - 1e-9:
                report.trip(
                    SafetyCause.CURRENT,
                    i,
                    f"motor current {current:.2f} A: near the limit of {limit:.2f} A for a net "
                    f"{self.timer_s[i]:.2f} s, before the actuator's own overload protection "
                    f"(guard: {self.rule.describe(i)})",
                )


class DeflectionWatch(Watch):
    def observe(self, sample: JointSample, report: Reporter) -> None:
        bound = self.context.safety.max_deflection_rad
        for i in range(self.context.n_joints):
            if not (sample.motor_valid[i] and sample.link_valid[i]):
                continue
            deflection = float(sample.link_angle_rad[i] - sample.motor_angle_rad[i])
            if abs(deflection) > bound:
                torque = abs(deflection) * self.context.stiffness_nm_per_rad[i]
                report.trip(
                    SafetyCause.DEFLECTION,
                    i,
                    f"gear deflection {deflection:+.4f} rad beyond +-{bound} rad "
                    f"({torque:.0f} N m at K)",
                )


@dataclass
class LinkHistory:
    """What the link watches remember of one joint's readings between ticks."""

    last_rad: float = math.nan
    before_rad: float = math.nan
    last_sampled_s: float = math.nan
    sampled_before_s: float = math.nan

    def forget(self) -> None:
        """A gap in the readings: differences across it would mean nothing."""
        self.last_rad = math.nan
        self.before_rad = math.nan

    def push(self, link: float, sampled_s: float) -> None:
        self.before_rad, self.last_rad = self.last_rad, link
        self.sampled_before_s, self.last_sampled_s = self.last_sampled_s, sampled_s


class LinkStaleWatch(Watch):
    def __init__(self, context: WatchContext, history: Sequence[LinkHistory]) -> None:
        super().__init__(context)
        n = context.n_joints
        self.history = history
        self.bad_ticks = np.zeros(n, dtype=int)
        self.bad_total = np.zeros(n, dtype=int)
        self.frozen_ticks = np.zeros(n, dtype=int)
        self.motor_at_freeze_rad = np.full(n, math.nan)

    def observe(self, sample: JointSample, report: Reporter) -> None:
        for i in range(self.context.n_joints):
            if sample.link_valid[i]:
                self._fresh(sample, report, i)
            else:
                self._missing(sample, report, i)

    def _missing(self, sample: JointSample, report: Reporter, i: int) -> None:
        s = self.context.safety
        self.bad_ticks[i] += 1
        self.bad_total[i] += 1
        self.history[i].forget()
        self.frozen_ticks[i] = 0
        if self.bad_ticks[i] >= s.link_stale_ticks:
            report.trip(
                SafetyCause.LINK_STALE,
                i,
                f"{self.context.devices[i].link_sensor}: no fresh position for "
                f"{self.bad_ticks[i]} ticks (last one {sample.link_age_s[i]:.3f} s ago)",
            )

    def _fresh(self, sample: JointSample, report: Reporter, i: int) -> None:
        s = self.context.safety
        sensor = self.context.devices[i].link_sensor
        if self.bad_ticks[i]:
            streak = (
                f"{sensor}: {self.bad_ticks[i]} tick(s) without a fresh position, then it "
                "answered again"
            )
            if self.bad_ticks[i] < s.link_stale_ticks:
                message = f"{streak}: tolerated (link_stale_ticks = {s.link_stale_ticks})"
                report.notice(NoticeKind.LINK_GLITCH, i, message)
            else:
                report.notice(
                    NoticeKind.LINK_RECOVERED, i, f"{streak}; the safe state stays latched"
                )
        self.bad_ticks[i] = 0
        link = float(sample.link_angle_rad[i])
        motor = float(sample.motor_angle_rad[i])
        if link != self.history[i].last_rad:
            self.frozen_ticks[i] = 0
            return
        if self.frozen_ticks[i] == 0:
            self.motor_at_freeze_rad[i] = motor
        self.frozen_ticks[i] += 1
        # A frozen reading while the motor turns far: a hung counter. A link blocked by an
        # obstacle also reads constant while the motor winds the gear up, but the windup stops
        # where the gear torque K x windup meets the actuator's torque limit (48 N m / 2000
        # N m/rad = 0.024 rad on the testbed), below half the deflection bound (0.03 rad); and
        # beyond the bound the deflection watch fires anyway.
        moved = abs(motor - self.motor_at_freeze_rad[i]) if sample.motor_valid[i] else 0.0
        if self.frozen_ticks[i] >= s.link_stale_ticks and moved > 0.5 * s.max_deflection_rad:
            report.trip(
                SafetyCause.LINK_STALE,
                i,
                f"{sensor}: position frozen for {self.frozen_ticks[i]} ticks while the motor "
                f"moved {moved:.4f} rad",
            )


class AlternationCounter:
    """Per joint, how many of the last `window` ticks had a second difference above
    `threshold` whose sign is opposite to the previous tick's (a reading that jumps back and
    forth; a physical motion's second difference changes sign only where its acceleration
    does, a few times per oscillation)."""

    def __init__(self, n_joints: int, window: int, threshold: float) -> None:
        self.threshold = threshold
        self.jumps = np.zeros((n_joints, window), dtype=bool)
        self.count = np.zeros(n_joints, dtype=int)
        self.index = np.zeros(n_joints, dtype=int)
        self.last = np.zeros(n_joints)

    @property
    def window(self) -> int:
        return self.jumps.shape[1]

    def add(self, joint: int, second_difference: float) -> int:
        """Count this tick's second difference; returns the joint's count over the window."""
        jump = abs(second_difference) > self.threshold and second_difference * self.last[joint] < 0
        slot = self.index[joint]
        self.count[joint] += int(jump) - int(self.jumps[joint, slot])
        self.jumps[joint, slot] = jump
        self.index[joint] = (slot + 1) % self.window
        self.last[joint] = second_difference
        return int(self.count[joint])

    def reset_sign(self, joint: int) -> None:
        """A gap in the readings: the next difference has no previous sign to alternate with."""
        self.last[joint] = 0.0


class LinkNoiseWatch(Watch):
    """The noise watch, one joint at a time (hil/safety/link_watches.py says what it does)."""

    def __init__(self, context: WatchContext, history: Sequence[LinkHistory]) -> None:
        super().__init__(context)
        n = context.n_joints
        s = context.safety
        window, threshold = s.link_noise_window_ticks, s.link_noise_jump_rad
        self.history = history
        self.link = AlternationCounter(n, window, threshold)
        self.motor = AlternationCounter(n, window, threshold)
        self.goal = AlternationCounter(n, window, threshold)
        self._motor = [_Trace() for _ in range(n)]
        self._goal = [_Trace() for _ in range(n)]
        self.trip_count = math.ceil(s.link_noise_fraction * window)
        self.reported = np.zeros(n, dtype=bool)

    def note_goal(self, goal_rad: np.ndarray) -> None:
        """The goal the supervisor sent this tick (its alternation is reported with a trip)."""
        for i, goal in enumerate(np.asarray(goal_rad, dtype=float)):
            second = self._goal[i].second_difference(float(goal), math.nan, self.context.period_s)
            if second is not None:
                self.goal.add(i, second)

    def observe(self, sample: JointSample, report: Reporter) -> None:
        period = self.context.period_s
        stamp = float(sample.timestamp_s)
        for i in range(self.context.n_joints):
            motor = float(sample.motor_angle_rad[i]) if sample.motor_valid[i] else math.nan
            second = self._motor[i].second_difference(motor, stamp, period)
            if second is None:
                self.motor.reset_sign(i)
            else:
                self.motor.add(i, second)
            history = self.history[i]
            if not sample.link_valid[i]:
                self.link.reset_sign(i)
                continue
            link = float(sample.link_angle_rad[i])
            if math.isfinite(history.before_rad):
                count = self.link.add(i, self._second_difference(history, link, stamp))
                if count >= self.trip_count and not self.reported[i]:
                    self.reported[i] = True
                    self._report(i, report)
            history.push(link, stamp)

    def _second_difference(self, history: LinkHistory, link: float, stamp: float) -> float:
        return _scaled(
            link - history.last_rad,
            history.last_rad - history.before_rad,
            stamp - history.last_sampled_s,
            history.last_sampled_s - history.sampled_before_s,
            self.context.period_s,
        )

    _report = product_link_watches.LinkNoiseWatch._report  # the same message


def _scaled(
    step_now: float, step_before: float, dt_now: float, dt_before: float, period_s: float
) -> float:
    """(slope now - slope before) x period over the sampling instants, or the plain second
    difference without usable timestamps (not increasing, or NaN)."""
    if dt_now > 0 and dt_before > 0:
        return (step_now / dt_now - step_before / dt_before) * period_s
    return step_now - step_before


class _Trace:
    """The last two readings of one signal and their instants: its next second difference."""

    def __init__(self) -> None:
        self.values = [math.nan, math.nan]  # before, last
        self.times = [math.nan, math.nan]

    def second_difference(self, value: float, time_s: float, period_s: float) -> float | None:
        """This reading's second difference (None while there are not three finite ones)."""
        (before, last), (t_before, t_last) = self.values, self.times
        self.values, self.times = [last, value], [t_last, time_s]
        if not (math.isfinite(before) and math.isfinite(last) and math.isfinite(value)):
            return None
        return _scaled(value - last, last - before, time_s - t_last, t_last - t_before, period_s)


def per_joint_watches(context: WatchContext, rule: GuardRule) -> Watches:
    """The supervisor's watch set (hil.safety.watch_set.Watches) made of the watches above."""
    history = [LinkHistory() for _ in range(context.n_joints)]
    return Watches(
        bus=BusErrorWatch(context),  # type: ignore[arg-type]
        actuator=ActuatorFaultWatch(context),  # type: ignore[arg-type]
        current=CurrentGuardWatch(context, rule),  # type: ignore[arg-type]
        link_stale=LinkStaleWatch(context, history),  # type: ignore[arg-type]
        link_noise=LinkNoiseWatch(context, history),  # type: ignore[arg-type]
        deflection=DeflectionWatch(context),  # type: ignore[arg-type]
        overrun=OverrunWatch(context),
    )


class PerJointSupervisor(Supervisor):
    """The supervisor with the reference watches and its command shaping as it was before it
    was trimmed (np.clip, a goal noted joint by joint)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        safety = self.safety
        self.watches = per_joint_watches(self.watches.overrun.context, self.watches.current.rule)
        assert self.watches.overrun.context.safety is safety

    def command(self, controller_goal: np.ndarray | None, sample: JointSample) -> np.ndarray | None:
        if self.state == SafeState.TORQUE_OFF:
            return None
        if self.state == SafeState.RUN:
            goal = controller_goal if controller_goal is not None else self._last_goal
            if goal is None:
                return None
            goal = np.asarray(goal, dtype=float)
            if goal.shape != self.min_goal.shape or not np.isfinite(goal).all():
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
        clipped = np.clip(goal, self.min_goal, self.max_goal)
        at_limit = clipped != goal
        self._watch_saturation(at_limit)
        if at_limit.any():
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
        limited = np.clip(clipped, low, high)
        self._rate_limited_total += limited != clipped
        return limited

    def _watch_saturation(self, at_limit: np.ndarray) -> None:
        slot = self._tick % self._clipped_recent.shape[0]
        self._clipped_recent_count += at_limit.astype(int) - self._clipped_recent[slot]
        self._clipped_recent[slot] = at_limit
        window = self._clipped_recent.shape[0]
        for i in np.flatnonzero(self._clipped_recent_count >= self._saturation_trip):
            self.trip(
                SafetyCause.GOAL_SATURATED,
                int(i),
                f"the goal was clipped at joint {self.names[i]!r}'s position limits on "
                f"{self._clipped_recent_count[i]} of the last {window} ticks: the controller "
                "is driving against the limits",
            )
