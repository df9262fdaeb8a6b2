"""The link encoder's watches: one remembers what the link reported, two judge it.

LinkStaleWatch  no fresh link value for `link_stale_ticks` ticks (a dead node), or a value
                frozen that long while the motor moved more than half the deflection bound
                (a hung counter)
LinkNoiseWatch  the link reading jumps back and forth (sign-alternating second difference),
                and whose fault that is: a noisy link encoder (the link jumps, the motor
                does not: `link_noisy`) or an oscillating joint (the motor moves back and
                forth with it, the goal alternates: `oscillation`, the controller or the
                plant, not the sensor). Both stop the run.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from drivers.joint_bus import JointSample
from hil.safety.watches import Reporter, Watch, WatchContext
from hil.vocabulary import NoticeKind, SafetyCause


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
    """Count sign-alternating jumps of the link reading's second difference, and tell a noisy
    encoder from an oscillating joint.

    A physical link angle sampled at 200 Hz has a smooth second difference (its sign changes only
    where the acceleration does, a few times per oscillation); white noise makes it alternate. A
    tick counts as a jump when |second difference| > `link_noise_jump_rad` and its sign is
    opposite to the previous tick's; the watch fires when at least `link_noise_fraction` of the
    last `link_noise_window_ticks` ticks are jumps. Measured on the emulated testbed (RLC2IC,
    983,040 counts/rev, 6.4e-6 rad per count): the contact and impact experiments with pid and
    gc+lqr+dob reach at most 2 of 20 (the 80 N impact included); the emulator's noisy_encoder
    fault (50 counts rms) 18 of 20. With the defaults, noise of about 1e-4 rad (16 counts) rms
    or more trips; quantisation (+-1 count) never counts.

    Whose fault: the same count runs on the motor angle (the actuator's own encoder, read in the
    same tick) and on the goals the supervisor sent. A noisy link encoder leaves the motor
    still: its count stays low. A joint that oscillates at the loop's rate - a controller
    chattering its goal from tick to tick, the servo and the gear following - moves the motor
    back and forth with the link (measured: 10 motor jumps in 20 where the link had 11, the goal
    16, gc+lqr standing on DYROS-JET). When the motor's count is at least half the trip count,
    the cause is `oscillation`, else `link_noisy`; the message gives all three counts. Only the
    first verdict per joint is reported.

    The second difference is taken over the readings' own timestamps (the SYNC instants), scaled
    to the nominal period: (slope now - slope before) x period. On the wall clock the sampling
    instants jitter by a fraction of a millisecond; a plain second difference of a link moving at
    1 rad/s would show that jitter as alternating jumps of ~1e-4 rad. Without usable timestamps
    (not increasing), the plain second difference is used.
    """

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

    def _report(self, i: int, report: Reporter) -> None:
        s = self.context.safety
        window = self.link.window
        counts = (
            f"link {self.link.count[i]}, motor {self.motor.count[i]}, goal {self.goal.count[i]} "
            f"of the last {window} ticks jumped back and forth by more than "
            f"{s.link_noise_jump_rad:g} rad (second difference)"
        )
        device = self.context.devices[i]
        if self.motor.count[i] * 2 >= self.trip_count:
            report.trip(
                SafetyCause.OSCILLATION,
                i,
                f"{device.actuator} and {device.link_sensor} oscillate together ({counts}): the "
                "joint oscillates at the loop's rate (the controller or the plant), not the sensor",
            )
        else:
            report.trip(
                SafetyCause.LINK_NOISY,
                i,
                f"{device.link_sensor}: the link jumps, the motor does not ({counts}): a noisy "
                "link encoder",
            )


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
