"""The supervisor's watches: one small class per thing that can go wrong, one method each.

Every watch looks at each tick's sample (`observe`) and reports through a `Reporter`: a `trip`
(a cause that latches a safe state) or a `notice` (worth a line in the log, changes nothing).
A watch keeps its own per-joint memory; it decides from the samples and the tick count, never
from the wall clock, so a lock-step run is deterministic. The supervisor runs them in the order
of `Watches` (hil/safety/watch_set.py; for one joint: actuator, link, deflection - the order of
the events). The link encoder's watches are in hil/safety/link_watches.py.

    BusErrorWatch       no valid reply from an actuator for `bus_error_ticks` ticks in a row
                        (timeouts, CRC errors, a missing ID); shorter streaks are notices
    ActuatorFaultWatch  the actuator's own protection: the fault it reports (read every tick in
                        the state block, so a trip is seen on the first read after it), or torque
                        found off while the loop expects it on
    CurrentGuardWatch   |current| held near the active current limit for too long (the software
                        overload guard, switchable; its rule: hil/safety/overload.py)
    LinkStaleWatch      (link_watches.py) no fresh link value for `link_stale_ticks` ticks (a
                        dead node), or a value frozen that long while the motor moved more than
                        half the deflection bound (a hung counter)
    LinkNoiseWatch      (link_watches.py) the link reading jumps back and forth
                        (sign-alternating 2nd difference): a noisy encoder (`link_noisy`), or,
                        with the motor moving back and forth too, an oscillating joint
                        (`oscillation`)
    DeflectionWatch     |theta_j - theta_m| beyond `max_deflection_rad`
    OverrunWatch        more than `overrun_limit` missed deadlines within `overrun_window_s`
                        (fed by the loop, not by samples)
"""

from __future__ import annotations

import abc
import collections
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from drivers.joint_bus import ActuatorFault, DeviceRole, JointDevices, JointSample
from hil.config import SafetySection
from hil.safety.overload import GuardRule
from hil.vocabulary import NoticeKind, SafetyCause


class Reporter(Protocol):
    """Where watches report (the supervisor: it adds the tick, the time and the joint name)."""

    def trip(
        self, cause: SafetyCause, joint: int | None, message: str, detail: object = None
    ) -> None: ...

    def notice(self, kind: NoticeKind, joint: int | None, message: str) -> None: ...


@dataclass(frozen=True)
class WatchContext:
    """What every watch may know: the configuration, the joints' devices, the loop period."""

    safety: SafetySection
    devices: tuple[JointDevices, ...]
    period_s: float
    stiffness_nm_per_rad: np.ndarray  # per joint, for the deflection watch's message

    @property
    def n_joints(self) -> int:
        return len(self.devices)


class Watch(abc.ABC):
    """One watch; `observe` runs once per tick on that tick's sample."""

    def __init__(self, context: WatchContext) -> None:
        self.context = context

    @abc.abstractmethod
    def observe(self, sample: JointSample, report: Reporter) -> None: ...


class BusErrorWatch(Watch):
    def __init__(self, context: WatchContext) -> None:
        super().__init__(context)
        n = context.n_joints
        self.bad_ticks = np.zeros(n, dtype=int)
        self.bad_total = np.zeros(n, dtype=int)
        self._reason = [""] * n
        self._streak = False  # some joint is in a streak of invalid replies

    def observe(self, sample: JointSample, report: Reporter) -> None:
        valid = sample.motor_valid
        if not self._streak and np.count_nonzero(valid) == valid.size:
            return
        limit = self.context.safety.bus_error_ticks
        bad_ticks = self.bad_ticks
        for i in np.flatnonzero(valid & (bad_ticks > 0)).tolist():
            streak = (
                f"{self.context.devices[i].actuator}: {bad_ticks[i]} tick(s) without a valid "
                f"reply ({self._reason[i]}), then it answered again"
            )
            if bad_ticks[i] < limit:
                message = f"{streak}: tolerated (bus_error_ticks = {limit})"
                report.notice(NoticeKind.BUS_GLITCH, i, message)
            else:
                message = f"{streak}; the safe state stays latched"
                report.notice(NoticeKind.BUS_RECOVERED, i, message)
        bad = np.logical_not(valid)
        bad_ticks *= bad
        bad_ticks += bad
        self.bad_total += bad
        self._streak = bool(np.count_nonzero(bad_ticks))
        for i in np.flatnonzero(bad).tolist():
            mine = sample.errors_of(i, DeviceRole.ACTUATOR)
            self._reason[i] = "; ".join(f.message for f in mine) or "no valid reply"
            if bad_ticks[i] >= limit:
                report.trip(
                    SafetyCause.BUS_ERROR,
                    i,
                    f"{self.context.devices[i].actuator}: {bad_ticks[i]} ticks in a row "
                    f"without a valid reply ({self._reason[i]})",
                )


class ActuatorFaultWatch(Watch):
    """Reports a fault whether or not the actuator has turned its torque off: an overheating
    warning outside the device's shutdown mask leaves torque on and still counts."""

    def __init__(self, context: WatchContext) -> None:
        super().__init__(context)
        self.expect_torque = False  # set by the supervisor when the loop turns torque on

    def observe(self, sample: JointSample, report: Reporter) -> None:
        n = sample.torque_enabled.size
        healthy = not np.count_nonzero(sample.actuator_fault)
        if healthy and (not self.expect_torque or np.count_nonzero(sample.torque_enabled) == n):
            return
        valid = sample.motor_valid
        faulted = valid & (sample.actuator_fault != 0)
        lost = valid & np.logical_not(sample.torque_enabled) if self.expect_torque else faulted
        for i in np.flatnonzero(faulted | lost).tolist():
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
            else:
                report.trip(
                    SafetyCause.TORQUE_LOST,
                    i,
                    f"{actuator} reads torque off without a fault (someone else turned torque "
                    "off, or the device restarted)",
                )


class CurrentGuardWatch(Watch):
    """The software overload guard: a timer per joint that runs up while |current| >= the
    rule's fraction of the active current limit and back down (never below 0) while it is not,
    firing at the rule's time (`GuardRule`, hil/safety/overload.py: derived from the actuator
    model's own protection, or the fixed figures). A timer that reset below the threshold would
    be fooled by a current dithering around it. A joint whose actuator did not answer this tick
    keeps its timer. `peak_timer_s`: the highest each timer ran (summary.json)."""

    def __init__(self, context: WatchContext, rule: GuardRule) -> None:
        super().__init__(context)
        n = context.n_joints
        self.rule = rule
        self.timer_s = np.zeros(n)
        self.peak_timer_s = np.zeros(n)
        self._fires_at_s = rule.time_s - 1e-9  # (the timer is a sum of periods)
        self.current_limit_a = np.full(n, np.nan)

    @property
    def current_limit_a(self) -> np.ndarray:
        return self._limit_a

    @current_limit_a.setter
    def current_limit_a(self, limit_a: np.ndarray) -> None:
        self._limit_a = limit_a
        self._near_a = self.rule.fraction * limit_a  # NaN: never near

    def observe(self, sample: JointSample, report: Reporter) -> None:
        if not self.context.safety.current_guard:
            return
        period = self.context.period_s
        valid = sample.motor_valid
        current = np.abs(sample.motor_current_a)
        step = np.where(current >= self._near_a, period, -period)
        if np.count_nonzero(valid) != valid.size:  # an unanswered joint keeps its timer
            step[np.logical_not(valid)] = 0.0
        timer = self.timer_s
        timer += step
        np.maximum(timer, 0.0, out=timer)
        np.maximum(self.peak_timer_s, timer, out=self.peak_timer_s)
        tripped = timer >= self._fires_at_s
        if not np.count_nonzero(tripped):
            return
        for i in np.flatnonzero(tripped & valid).tolist():
            report.trip(
                SafetyCause.CURRENT,
                i,
                f"motor current {current[i]:.2f} A: near the limit of {self.current_limit_a[i]:.2f}"
                f" A for a net {timer[i]:.2f} s, before the actuator's own overload protection "
                f"(guard: {self.rule.describe(i)})",
            )


class DeflectionWatch(Watch):
    def observe(self, sample: JointSample, report: Reporter) -> None:
        bound = self.context.safety.max_deflection_rad
        deflection = sample.link_angle_rad - sample.motor_angle_rad  # NaN where either is unread
        beyond = np.abs(deflection) > bound
        if not np.count_nonzero(beyond):
            return
        for i in np.flatnonzero(beyond & sample.motor_valid & sample.link_valid).tolist():
            torque = abs(float(deflection[i])) * self.context.stiffness_nm_per_rad[i]
            report.trip(
                SafetyCause.DEFLECTION,
                i,
                f"gear deflection {float(deflection[i]):+.4f} rad beyond +-{bound} rad "
                f"({torque:.0f} N m at K)",
            )


class OverrunWatch:
    """Missed deadlines over a sliding window; fed by the loop (`note`), not by samples.

    A missed deadline counts once plus once per skipped tick (a 100 ms stall at 200 Hz counts
    20), over a sliding window of `overrun_window_s`.
    """

    def __init__(self, context: WatchContext) -> None:
        self.context = context
        self.total = 0
        self._window_ticks = max(1, round(context.safety.overrun_window_s / context.period_s))
        self._recent: collections.deque[tuple[int, int]] = collections.deque()
        self._recent_count = 0

    def note(self, tick: int, skipped: int, report: Reporter) -> None:
        s = self.context.safety
        weight = 1 + max(0, int(skipped))
        self.total += weight
        self._recent.append((tick, weight))
        self._recent_count += weight
        oldest = tick - self._window_ticks
        while self._recent and self._recent[0][0] <= oldest:
            self._recent_count -= self._recent.popleft()[1]
        if self._recent_count > s.overrun_limit:
            report.trip(
                SafetyCause.OVERRUN,
                None,
                f"{self._recent_count} missed deadlines within {s.overrun_window_s:g} s "
                f"(limit {s.overrun_limit}); this one skipped {skipped} tick(s)",
            )
