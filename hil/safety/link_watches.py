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

import numpy as np

from drivers.joint_bus import JointSample
from hil.safety.alternation import (
    AlternationCounter,
    CounterPart,
    SecondDifference,
    scaled_second_difference,
)
from hil.safety.watches import Reporter, Watch, WatchContext
from hil.vocabulary import NoticeKind, SafetyCause


class LinkHistory:
    """What the link watches remember of every joint's readings between ticks (arrays over the
    joints). `uniform`: every joint's last two readings were taken together, at `instants_s`
    (before, last)."""

    def __init__(self, n_joints: int) -> None:
        self.last_rad = np.full(n_joints, math.nan)
        self.before_rad = np.full(n_joints, math.nan)
        self.last_sampled_s = np.full(n_joints, math.nan)
        self.sampled_before_s = np.full(n_joints, math.nan)
        self.instants_s = (math.nan, math.nan)
        self._together = 0  # pushes in a row that took every joint (up to 2)

    @property
    def uniform(self) -> bool:
        return self._together >= 2

    def forget(self, joints: np.ndarray) -> None:
        """A gap in the readings of these joints (a mask): differences across it would mean
        nothing."""
        self.last_rad[joints] = math.nan
        self.before_rad[joints] = math.nan

    def push(self, joints: np.ndarray, link: np.ndarray, sampled_s: float, every: bool) -> None:
        """The readings of these joints (a mask; `every`: all of them) at `sampled_s`."""
        if every:  # the oldest arrays take the newest values: no allocation
            self.before_rad, self.last_rad = self.last_rad, self.before_rad
            self.last_rad[:] = link
            self.sampled_before_s, self.last_sampled_s = self.last_sampled_s, self.sampled_before_s
            self.last_sampled_s.fill(sampled_s)
            self.instants_s = (self.instants_s[1], sampled_s)
            self._together = min(self._together + 1, 2)
            return
        self.before_rad[joints] = self.last_rad[joints]
        self.last_rad[joints] = link[joints]
        self.sampled_before_s[joints] = self.last_sampled_s[joints]
        self.last_sampled_s[joints] = sampled_s
        self._together = 0


class LinkStaleWatch(Watch):
    def __init__(self, context: WatchContext, history: LinkHistory) -> None:
        super().__init__(context)
        n = context.n_joints
        self.history = history
        self.bad_ticks = np.zeros(n, dtype=int)
        self.bad_total = np.zeros(n, dtype=int)
        self.frozen_ticks = np.zeros(n, dtype=int)
        self.motor_at_freeze_rad = np.full(n, math.nan)
        self._streak = False  # some joint is in a streak of missing readings

    def observe(self, sample: JointSample, report: Reporter) -> None:
        s = self.context.safety
        valid = sample.link_valid
        every = np.count_nonzero(valid) == valid.size
        missing = np.logical_not(valid)
        stale = None
        if self._streak or not every:
            self._glitches(valid, report)
            self.bad_ticks *= missing
            self.bad_ticks += missing
            self.bad_total += missing
            self.history.forget(missing)
            self.frozen_ticks *= valid
            self._streak = not every
            stale = missing & (self.bad_ticks >= s.link_stale_ticks)
        # A fresh reading equal to the last one: the link did not move, or the counter hung.
        link, motor = sample.link_angle_rad, sample.motor_angle_rad
        same = link == self.history.last_rad  # NaN (after a gap) is never the same
        if not every:
            same &= valid
        frozen = None
        if np.count_nonzero(same):
            self.frozen_ticks *= missing | same
            starting = same & (self.frozen_ticks == 0)
            self.motor_at_freeze_rad[starting] = motor[starting]
            self.frozen_ticks += same
            # A frozen reading while the motor turns far: a hung counter. A link blocked by an
            # obstacle also reads constant while the motor winds the gear up, but the windup
            # stops where the gear torque K x windup meets the actuator's torque limit
            # (48 N m / 2000 N m/rad = 0.024 rad on the testbed), below half the deflection
            # bound (0.03 rad); and beyond the bound the deflection watch fires anyway.
            frozen = same & (self.frozen_ticks >= s.link_stale_ticks)
            if np.count_nonzero(frozen):
                moved = np.where(sample.motor_valid, np.abs(motor - self.motor_at_freeze_rad), 0.0)
                frozen &= moved > 0.5 * s.max_deflection_rad
        else:
            self.frozen_ticks.fill(0)
        if stale is None and frozen is None:
            return
        trips = stale if frozen is None else frozen if stale is None else stale | frozen
        for i in np.flatnonzero(trips).tolist():
            self._trip(sample, report, i)

    def _glitches(self, valid: np.ndarray, report: Reporter) -> None:
        """Notices for the joints that answered again after a streak without a reading."""
        s = self.context.safety
        for i in np.flatnonzero(valid & (self.bad_ticks > 0)).tolist():
            streak = (
                f"{self.context.devices[i].link_sensor}: {self.bad_ticks[i]} tick(s) without a "
                "fresh position, then it answered again"
            )
            if self.bad_ticks[i] < s.link_stale_ticks:
                message = f"{streak}: tolerated (link_stale_ticks = {s.link_stale_ticks})"
                report.notice(NoticeKind.LINK_GLITCH, i, message)
            else:
                report.notice(
                    NoticeKind.LINK_RECOVERED, i, f"{streak}; the safe state stays latched"
                )

    def _trip(self, sample: JointSample, report: Reporter, i: int) -> None:
        sensor = self.context.devices[i].link_sensor
        if not sample.link_valid[i]:
            report.trip(
                SafetyCause.LINK_STALE,
                i,
                f"{sensor}: no fresh position for {self.bad_ticks[i]} ticks (last one "
                f"{sample.link_age_s[i]:.3f} s ago)",
            )
            return
        moved = abs(float(sample.motor_angle_rad[i]) - self.motor_at_freeze_rad[i])
        report.trip(
            SafetyCause.LINK_STALE,
            i,
            f"{sensor}: position frozen for {self.frozen_ticks[i]} ticks while the motor "
            f"moved {moved:.4f} rad",
        )


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

    def __init__(self, context: WatchContext, history: LinkHistory) -> None:
        super().__init__(context)
        n = context.n_joints
        s = context.safety
        window, threshold = s.link_noise_window_ticks, s.link_noise_jump_rad
        self.history = history
        # the motor's and the link's counts in one counter: joints 0..n-1 and n..2n-1
        self._signals = AlternationCounter(2 * n, window, threshold)
        self.motor = CounterPart(self._signals, slice(0, n))
        self.link = CounterPart(self._signals, slice(n, 2 * n))
        self.goal = AlternationCounter(n, window, threshold)
        self._motor = SecondDifference(n)
        self._goal = SecondDifference(n)
        self.trip_count = math.ceil(s.link_noise_fraction * window)
        self.reported = np.zeros(n, dtype=bool)
        self._motor_reading = np.zeros(n)
        self._second = np.zeros(2 * n)  # this tick's second differences: motor, link
        self._added = np.zeros(2 * n, dtype=bool)
        self._scratch = np.zeros(n)

    def note_goal(self, goal_rad: np.ndarray) -> None:
        """The goal the supervisor sent this tick (its alternation is reported with a trip)."""
        second, defined = self._goal.update(goal_rad, math.nan, self.context.period_s)
        if defined is not None:
            self.goal.add(second, None if defined is True else defined)

    def observe(self, sample: JointSample, report: Reporter) -> None:
        period = self.context.period_s
        stamp = float(sample.timestamp_s)
        n = self.reported.size
        motor = sample.motor_angle_rad
        if np.count_nonzero(sample.motor_valid) != n:
            motor = self._motor_reading
            np.copyto(motor, sample.motor_angle_rad)
            motor[np.logical_not(sample.motor_valid)] = math.nan
        _, defined = self._motor.update(motor, stamp, period, out=self._second[:n])
        if defined is not True:
            self.motor.reset_sign(None if defined is None else np.logical_not(defined))
        counted, every = self._link_second_difference(sample, stamp, period)
        n_counted = np.count_nonzero(counted)
        if defined is True and n_counted == n:
            self._signals.add(self._second)
        elif defined is not None or n_counted:
            added = self._added
            added[:n] = False if defined is None else defined  # (True, or a mask)
            added[n:] = counted
            self._signals.add(self._second, added)
        if n_counted:
            news = self.link.count >= self.trip_count
            if np.count_nonzero(news):
                news &= counted & np.logical_not(self.reported)
                for i in np.flatnonzero(news).tolist():
                    self.reported[i] = True
                    self._report(i, report)
        self.history.push(sample.link_valid, sample.link_angle_rad, stamp, every)

    def _link_second_difference(
        self, sample: JointSample, stamp: float, period: float
    ) -> tuple[np.ndarray, bool]:
        """The link reading's second differences (into the second half of `_second`), where
        they count (a mask: the joints read now whose last two readings are known), and
        whether every joint was read."""
        history = self.history
        valid, link = sample.link_valid, sample.link_angle_rad
        n = valid.size
        every = bool(np.count_nonzero(valid) == n)
        if not every:
            self.link.reset_sign(np.logical_not(valid))
        counted = np.isfinite(history.before_rad)
        if not every:
            counted &= valid
        if not np.count_nonzero(counted):
            return counted, every
        last, before = history.last_rad, history.before_rad
        out = self._second[n:]
        if history.uniform:  # one instant for every joint: the same operations, in place
            before_s, last_s = history.instants_s
            dt_now, dt_before = stamp - last_s, last_s - before_s
            if dt_now > 0 and dt_before > 0:
                slope_before = self._scratch
                np.divide(np.subtract(last, before, out=slope_before), dt_before, out=slope_before)
                np.divide(np.subtract(link, last, out=out), dt_now, out=out)
                out -= slope_before
                out *= period
                return counted, every
        else:
            dt_now = stamp - history.last_sampled_s
            dt_before = history.last_sampled_s - history.sampled_before_s
        out[:] = scaled_second_difference(link - last, last - before, dt_now, dt_before, period)
        return counted, every

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
