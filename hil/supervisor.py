"""The safety supervisor: between the controller and the bus, every tick.

What it does each tick, in this order:
1. watch the sample (`observe`):
       hardware_error  the actuator's own protection: Hardware Error Status (892) is part of the
                       state block read every tick, so a trip is seen on the first read after
                       it; decoded (overload, electrical shock, encoder, hall sensor,
                       overheating, input voltage) and reported with joint and time
       torque_lost     the actuator reads torque off while the loop expects it on
       bus_error       no valid reply from an actuator for `bus_error_ticks` ticks in a row
                       (timeouts, CRC errors, a missing ID); shorter streaks are tolerated and
                       recorded as notices
       link_stale      no fresh link-encoder value for `link_stale_ticks` ticks (a dead node),
                       or a value frozen for `link_stale_ticks` ticks while the motor moved
                       more than half the deflection bound (a hung counter; see `_watch_link`
                       for why an obstacle contact does not count)
       link_noisy      the link reading jumps back and forth (see `_watch_noise`)
       deflection      |theta_j - theta_m| beyond `max_deflection_rad`
       current         |motor current| held near the active current limit for too long (the
                       software overload guard, switchable; see `_watch_current`)
       overrun         more than `overrun_limit` missed deadlines within `overrun_window_s`
                       (`note_overrun`, from the loop)
2. when a watch fires, latch the configured safe state for that cause and record it with the
   joint, the tick, the time and the figures (`events`); each cause is reported once per joint;
3. shape the command (`command`): in normal running, reject a non-finite goal
   (`command_invalid`), clip each goal to its joint's position limits and to the goal rate
   limit; in a safe state, replace it:
       hold        keep the motor where it was when the state was entered
       back_off    move the goal `current_guard_backoff_rad` away from the direction the motor
                   was pushing (sign of its current: relieves a load or a contact), then hold
       torque_off  torque off on every joint (the loop calls `bus.disable()`), no more goals
   A later, more severe cause escalates (hold -> back_off -> torque_off), never the reverse.
Recovery is never automatic: a latched safe state lasts until the run ends; clearing an
actuator's hardware error takes an explicit `hil reboot` or `hil run --reboot-first`
(see hil/recovery.py for the slow re-homing that follows).

Everything here is decided from the samples and the tick count, never from the wall clock, so a
lock-step run is deterministic.
"""

from __future__ import annotations

import collections
import enum
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from drivers.joint_bus import HardwareError, JointSample
from hil.config import REACTIONS, JointConfig, SafetyConfig

MAX_NOTICES_PER_KIND = 20  # per joint and kind; later ones are only counted (summary.json)


class ReferenceOutsideLimits(ValueError):
    """An experiment's reference leaves a joint's range: refused before any port is opened."""


class SafeState(enum.IntEnum):
    """The supervisor's state, ordered by severity."""

    RUN = 0
    HOLD = 1
    BACK_OFF = 2
    TORQUE_OFF = 3

    @classmethod
    def from_reaction(cls, reaction: str) -> SafeState:
        try:
            return {"hold": cls.HOLD, "back_off": cls.BACK_OFF, "torque_off": cls.TORQUE_OFF}[
                reaction
            ]
        except KeyError:
            raise ValueError(
                f"unknown safety reaction {reaction!r}; expected one of {list(REACTIONS)}"
            ) from None


@dataclass(frozen=True)
class SafetyEvent:
    """A watch fired: `action` is the reaction configured for the cause, `state` the
    supervisor's state after it (a milder cause after a severe one leaves the severe state)."""

    tick: int
    time_s: float
    cause: str  # hardware_error, torque_lost, bus_error, link_stale, link_noisy, deflection,
    # current, command_invalid, overrun
    joint: str | None
    action: str  # hold, back_off, torque_off
    message: str
    state: str = ""


@dataclass(frozen=True)
class SafetyNotice:
    """Something worth a line in the log that does not change the state: a tolerated bus or
    encoder glitch, a goal clipped at a position limit."""

    tick: int
    time_s: float
    kind: str  # bus_glitch, link_glitch, bus_recovered, link_recovered, goal_limited
    joint: str | None
    message: str


@dataclass(frozen=True)
class WatchTuning:
    """Figures of the watches that the configuration file does not carry (yet).

    link_noise_*: the link-encoder noise watch. A physical link angle sampled at 200 Hz has a
        smooth second difference (its sign changes only where the acceleration does, a few
        times per oscillation); white noise makes it alternate. The second difference is taken
        over the readings' timestamps, so that sampling jitter on the wall clock does not look
        like noise. A tick counts as a noise jump when |second difference| >
        `link_noise_jump_rad` and its sign is opposite to the previous tick's. The watch fires
        when at least `link_noise_fraction` of the last `link_noise_window_ticks` ticks are
        noise jumps. Measured on the emulated testbed (RLC2IC, 983,040 counts/rev, 6.4e-6 rad
        per count): the contact and impact experiments with pid and gc+lqr+dob reach at most
        2 of 20 (the 80 N impact included); the emulator's noisy_encoder fault (50 counts rms)
        18 of 20. With these figures, noise of about 1e-4 rad (16 counts) rms or more trips;
        quantisation (+-1 count) never counts.
    overrun_window_s: missed deadlines are counted over this sliding window.
    on_link_noisy / on_command_invalid: the reactions for those two causes.
    """

    link_noise_jump_rad: float = 1.0e-4
    link_noise_window_ticks: int = 20
    link_noise_fraction: float = 0.5
    overrun_window_s: float = 1.0
    on_link_noisy: str = "hold"
    on_command_invalid: str = "hold"

    def __post_init__(self) -> None:
        if not self.link_noise_jump_rad > 0:
            raise ValueError(f"link_noise_jump_rad must be > 0, got {self.link_noise_jump_rad}")
        if self.link_noise_window_ticks < 2:
            raise ValueError(
                f"link_noise_window_ticks must be >= 2, got {self.link_noise_window_ticks}"
            )
        if not 0 < self.link_noise_fraction <= 1:
            raise ValueError(
                f"link_noise_fraction must be in (0, 1], got {self.link_noise_fraction}"
            )
        if not self.overrun_window_s > 0:
            raise ValueError(f"overrun_window_s must be > 0, got {self.overrun_window_s}")
        for key in ("on_link_noisy", "on_command_invalid"):
            SafeState.from_reaction(getattr(self, key))


@dataclass
class _JointWatch:
    """What the watches remember about one joint between ticks."""

    overload_timer_s: float = 0.0
    motor_bad_ticks: int = 0
    motor_bad_reason: str = ""
    link_bad_ticks: int = 0
    link_frozen_ticks: int = 0
    last_link_rad: float = math.nan
    link_before_rad: float = math.nan
    last_second_difference_rad: float = 0.0
    last_sampled_s: float = math.nan
    sampled_before_s: float = math.nan
    motor_at_freeze_rad: float = math.nan
    noise_jumps: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    noise_jump_count: int = 0
    noise_index: int = 0


@dataclass
class Supervisor:
    """See the module docstring. One instance per run; `current_limit_a` are the actuators'
    active current caps, the reference of the software overload guard."""

    safety: SafetyConfig
    joints: Sequence[JointConfig]
    period_s: float
    current_limit_a: np.ndarray
    tuning: WatchTuning = field(default_factory=WatchTuning)
    state: SafeState = SafeState.RUN
    events: list[SafetyEvent] = field(default_factory=list)
    notices: list[SafetyNotice] = field(default_factory=list)
    overruns: int = 0

    def __post_init__(self) -> None:
        n = len(self.joints)
        if n == 0:
            raise ValueError("the supervisor needs at least one joint")
        if not self.period_s > 0:
            raise ValueError(f"period_s must be > 0, got {self.period_s}")
        for key in (
            "on_hardware_error",
            "on_deflection",
            "on_current",
            "on_link_stale",
            "on_bus_error",
            "on_overrun",
        ):
            SafeState.from_reaction(getattr(self.safety, key))
        self.names = tuple(j.name for j in self.joints)
        self.min_goal = np.array([j.min_angle_rad for j in self.joints], dtype=float)
        self.max_goal = np.array([j.max_angle_rad for j in self.joints], dtype=float)
        if not np.all(self.min_goal < self.max_goal):
            raise ValueError("every joint needs min_angle_rad < max_angle_rad")
        self.max_goal_step = np.full(n, self.safety.max_goal_rate_rad_s * self.period_s)
        if not np.all(self.max_goal_step > 0):
            raise ValueError(
                f"max_goal_rate_rad_s must be > 0, got {self.safety.max_goal_rate_rad_s}"
            )
        self.set_current_limits(self.current_limit_a)
        window = self.tuning.link_noise_window_ticks
        self._watch = [_JointWatch(noise_jumps=np.zeros(window, dtype=bool)) for _ in range(n)]
        self._noise_trip_count = math.ceil(self.tuning.link_noise_fraction * window)
        self._overrun_window_ticks = max(1, round(self.tuning.overrun_window_s / self.period_s))
        self._recent_overruns: collections.deque[tuple[int, int]] = collections.deque()
        self._recent_overrun_count = 0
        self._reported: set[tuple[Any, ...]] = set()
        self._hold_goal: np.ndarray | None = None
        self._hold_state = SafeState.RUN
        self._last_goal: np.ndarray | None = None
        self._expect_torque = False
        self._tick = 0
        self._time_s = 0.0
        self._notice_counts: collections.Counter[tuple[str, str | None]] = collections.Counter()
        self._bus_bad_total = np.zeros(n, dtype=int)
        self._link_bad_total = np.zeros(n, dtype=int)
        self._clipped_total = np.zeros(n, dtype=int)
        self._rate_limited_total = np.zeros(n, dtype=int)

    # --- lifecycle -------------------------------------------------------------------------
    def torque_enabled(self, goal_rad: np.ndarray) -> None:
        """The loop turned torque on with this goal (the present motor angle)."""
        self._expect_torque = True
        self._last_goal = np.array(goal_rad, dtype=float)

    def torque_disabled(self) -> None:
        self._expect_torque = False

    @property
    def safe(self) -> bool:
        """True once any cause has latched a safe state."""
        return self.state != SafeState.RUN

    @property
    def first_trip(self) -> SafetyEvent | None:
        return self.events[0] if self.events else None

    def counters(self) -> dict[str, Any]:
        """Totals for summary.json: what was tolerated or shaped, per joint."""

        def per_joint(counts: np.ndarray) -> dict[str, int]:
            return dict(zip(self.names, counts.tolist(), strict=True))

        return {
            "motor_invalid_ticks": per_joint(self._bus_bad_total),
            "link_invalid_ticks": per_joint(self._link_bad_total),
            "goals_clipped_at_limit": per_joint(self._clipped_total),
            "goals_rate_limited": per_joint(self._rate_limited_total),
            "overruns": self.overruns,
        }

    # --- 1. watch ----------------------------------------------------------------------------
    def note_overrun(self, tick: int, time_s: float, skipped: int) -> None:
        """The loop missed a deadline this tick; `skipped` grid ticks were lost entirely.

        A missed deadline counts once plus once per skipped tick (a 100 ms stall at 200 Hz
        counts 20), over a sliding window of `overrun_window_s`.
        """
        weight = 1 + max(0, int(skipped))
        self.overruns += weight
        self._recent_overruns.append((tick, weight))
        self._recent_overrun_count += weight
        oldest = tick - self._overrun_window_ticks
        while self._recent_overruns and self._recent_overruns[0][0] <= oldest:
            self._recent_overrun_count -= self._recent_overruns.popleft()[1]
        if self._recent_overrun_count > self.safety.overrun_limit:
            self._trip(
                tick,
                time_s,
                "overrun",
                None,
                self.safety.on_overrun,
                f"{self._recent_overrun_count} missed deadlines within "
                f"{self.tuning.overrun_window_s:g} s (limit {self.safety.overrun_limit}); "
                f"this one skipped {skipped} tick(s)",
            )

    def observe(self, tick: int, time_s: float, sample: JointSample) -> list[SafetyEvent]:
        """Run every watch on this tick's sample; returns the events it raised."""
        self._tick, self._time_s = tick, time_s
        before = len(self.events)
        for i in range(len(self.joints)):
            if sample.motor_valid[i]:
                self._motor_answered(tick, time_s, i, sample)
            else:
                self._motor_silent(tick, time_s, i, sample)
            self._watch_link(tick, time_s, i, sample)
            if sample.motor_valid[i] and sample.link_valid[i]:
                self._watch_deflection(tick, time_s, i, sample)
        return self.events[before:]

    def _motor_answered(self, tick: int, time_s: float, i: int, sample: JointSample) -> None:
        s = self.safety
        w = self._watch[i]
        joint = self.joints[i]
        if w.motor_bad_ticks:
            streak = (
                f"actuator {joint.dynamixel_id}: {w.motor_bad_ticks} tick(s) without a valid "
                f"reply ({w.motor_bad_reason}), then it answered again"
            )
            if w.motor_bad_ticks < s.bus_error_ticks:
                message = f"{streak}: tolerated (bus_error_ticks = {s.bus_error_ticks})"
                self._notice(tick, time_s, "bus_glitch", i, message)
            else:
                message = f"{streak}; the safe state stays latched"
                self._notice(tick, time_s, "bus_recovered", i, message)
        w.motor_bad_ticks = 0
        bits = int(sample.hardware_error[i])
        if bits:
            self._trip(
                tick,
                time_s,
                "hardware_error",
                self.names[i],
                s.on_hardware_error,
                f"actuator {joint.dynamixel_id} reports Hardware Error Status 0x{bits:02X} "
                f"({HardwareError.describe(bits)}); torque is "
                f"{'on' if sample.torque_enabled[i] else 'off'}",
                detail=bits,
            )
        elif self._expect_torque and not sample.torque_enabled[i]:
            self._trip(
                tick,
                time_s,
                "torque_lost",
                self.names[i],
                s.on_hardware_error,
                f"actuator {joint.dynamixel_id} reads torque off without a hardware error "
                "(someone else wrote Torque Enable, or the device restarted)",
            )
        self._watch_current(tick, time_s, i, abs(float(sample.motor_current_a[i])))

    def _motor_silent(self, tick: int, time_s: float, i: int, sample: JointSample) -> None:
        s = self.safety
        w = self._watch[i]
        joint = self.joints[i]
        w.motor_bad_ticks += 1
        self._bus_bad_total[i] += 1
        prefix = f"ID {joint.dynamixel_id} "
        mine = [e for e in sample.bus_errors if e.startswith(prefix)]
        w.motor_bad_reason = "; ".join(mine or sample.bus_errors) or "no valid reply"
        if w.motor_bad_ticks >= s.bus_error_ticks:
            self._trip(
                tick,
                time_s,
                "bus_error",
                self.names[i],
                s.on_bus_error,
                f"actuator {joint.dynamixel_id}: {w.motor_bad_ticks} ticks in a row without a "
                f"valid reply ({w.motor_bad_reason})",
            )

    def _watch_current(self, tick: int, time_s: float, i: int, current_a: float) -> None:
        """The software overload guard.

        A timer runs up while |current| >= current_guard_fraction x the active current limit
        and back down (never below 0) while it is not, as the emulated actuator's own overload
        timer does (sim_backend/servo.py; ROBOTIS publish no threshold). With a fraction below
        the actuator's (0.8 < 0.9) and a time below its (0.6 s < 1.5 s), every tick that runs
        the actuator's timer up runs this one up too, so the guard fires first.
        """
        s = self.safety
        if not s.current_guard:
            return
        w = self._watch[i]
        near = current_a >= s.current_guard_fraction * self.current_limit_a[i]  # False if NaN
        step = self.period_s if near else -self.period_s
        w.overload_timer_s = max(0.0, w.overload_timer_s + step)
        if w.overload_timer_s >= s.current_guard_time_s - 1e-9:
            self._trip(
                tick,
                time_s,
                "current",
                self.names[i],
                s.on_current,
                f"motor current {current_a:.2f} A: near the limit (>= "
                f"{s.current_guard_fraction:.0%} of {self.current_limit_a[i]:.2f} A) for a net "
                f"{w.overload_timer_s:.2f} s, before the actuator's own overload protection",
            )

    def _watch_deflection(self, tick: int, time_s: float, i: int, sample: JointSample) -> None:
        s = self.safety
        deflection = float(sample.link_angle_rad[i] - sample.motor_angle_rad[i])
        if abs(deflection) > s.max_deflection_rad:
            self._trip(
                tick,
                time_s,
                "deflection",
                self.names[i],
                s.on_deflection,
                f"gear deflection {deflection:+.4f} rad beyond +-{s.max_deflection_rad} rad "
                f"({abs(deflection) * self.joints[i].stiffness_nm_per_rad:.0f} N m at K)",
            )

    def _watch_link(self, tick: int, time_s: float, i: int, sample: JointSample) -> None:
        s = self.safety
        w = self._watch[i]
        node = self.joints[i].encoder_node_id
        if not sample.link_valid[i]:
            w.link_bad_ticks += 1
            self._link_bad_total[i] += 1
            self._forget_link_history(w)
            if w.link_bad_ticks >= s.link_stale_ticks:
                self._trip(
                    tick,
                    time_s,
                    "link_stale",
                    self.names[i],
                    s.on_link_stale,
                    f"link encoder node {node}: no fresh position for {w.link_bad_ticks} ticks "
                    f"(last one {sample.link_age_s[i]:.3f} s ago)",
                )
            return
        if w.link_bad_ticks:
            streak = (
                f"link encoder node {node}: {w.link_bad_ticks} tick(s) without a fresh "
                "position, then it answered again"
            )
            if w.link_bad_ticks < s.link_stale_ticks:
                message = f"{streak}: tolerated (link_stale_ticks = {s.link_stale_ticks})"
                self._notice(tick, time_s, "link_glitch", i, message)
            else:
                message = f"{streak}; the safe state stays latched"
                self._notice(tick, time_s, "link_recovered", i, message)
        w.link_bad_ticks = 0
        link = float(sample.link_angle_rad[i])
        motor = float(sample.motor_angle_rad[i])
        if link == w.last_link_rad:
            if w.link_frozen_ticks == 0:
                w.motor_at_freeze_rad = motor
            w.link_frozen_ticks += 1
            # A frozen reading while the motor turns far: a hung counter. A link blocked by an
            # obstacle also reads constant while the motor winds the gear up, but the windup
            # stops where the gear torque K x windup meets the actuator's torque limit
            # (48 N m / 2000 N m/rad = 0.024 rad on the testbed), below half the deflection
            # bound (0.03 rad); and beyond the bound the deflection watch fires anyway.
            moved = abs(motor - w.motor_at_freeze_rad) if sample.motor_valid[i] else 0.0
            if w.link_frozen_ticks >= s.link_stale_ticks and moved > 0.5 * s.max_deflection_rad:
                self._trip(
                    tick,
                    time_s,
                    "link_stale",
                    self.names[i],
                    s.on_link_stale,
                    f"link encoder node {node}: position frozen for {w.link_frozen_ticks} ticks "
                    f"while the motor moved {moved:.4f} rad",
                )
        else:
            w.link_frozen_ticks = 0
        self._watch_noise(tick, time_s, i, link, float(sample.timestamp_s))

    def _watch_noise(self, tick: int, time_s: float, i: int, link: float, sampled_s: float) -> None:
        """Count sign-alternating jumps of the link reading's second difference (WatchTuning).

        The second difference is taken over the readings' own timestamps (the SYNC instants),
        scaled to the nominal period: (slope now - slope before) x period. On the wall clock
        the sampling instants jitter by a fraction of a millisecond; a plain second difference
        of a link moving at 1 rad/s would show that jitter as alternating jumps of ~1e-4 rad.
        Without usable timestamps (not increasing), the plain second difference is used.
        """
        t = self.tuning
        w = self._watch[i]
        if math.isfinite(w.link_before_rad):
            step_now = sampled_s - w.last_sampled_s
            step_before = w.last_sampled_s - w.sampled_before_s
            if step_now > 0 and step_before > 0:
                slope_now = (link - w.last_link_rad) / step_now
                slope_before = (w.last_link_rad - w.link_before_rad) / step_before
                second = (slope_now - slope_before) * self.period_s
            else:
                second = link - 2.0 * w.last_link_rad + w.link_before_rad
            jump = abs(second) > t.link_noise_jump_rad and second * w.last_second_difference_rad < 0
            w.noise_jump_count += int(jump) - int(w.noise_jumps[w.noise_index])
            w.noise_jumps[w.noise_index] = jump
            w.noise_index = (w.noise_index + 1) % len(w.noise_jumps)
            w.last_second_difference_rad = second
            if w.noise_jump_count >= self._noise_trip_count:
                self._trip(
                    tick,
                    time_s,
                    "link_noisy",
                    self.names[i],
                    t.on_link_noisy,
                    f"link encoder node {self.joints[i].encoder_node_id}: {w.noise_jump_count} "
                    f"of the last {len(w.noise_jumps)} readings jumped back and forth by more "
                    f"than {t.link_noise_jump_rad:g} rad (second difference): a noisy sensor",
                )
        w.link_before_rad = w.last_link_rad
        w.last_link_rad = link
        w.sampled_before_s = w.last_sampled_s
        w.last_sampled_s = sampled_s

    @staticmethod
    def _forget_link_history(w: _JointWatch) -> None:
        """A gap in the readings: differences across it would mean nothing."""
        w.last_link_rad = math.nan
        w.link_before_rad = math.nan
        w.last_second_difference_rad = 0.0
        w.link_frozen_ticks = 0

    # --- 2. latch and record ------------------------------------------------------------------
    def _trip(
        self,
        tick: int,
        time_s: float,
        cause: str,
        joint: str | None,
        reaction: str,
        message: str,
        *,
        detail: Any = None,
    ) -> None:
        key = (cause, joint, detail)
        if key in self._reported:
            return
        self._reported.add(key)
        target = SafeState.from_reaction(reaction)
        if target > self.state:
            self.state = target
        self.events.append(
            SafetyEvent(tick, time_s, cause, joint, reaction, message, self.state.name.lower())
        )

    def _notice(self, tick: int, time_s: float, kind: str, i: int | None, message: str) -> None:
        joint = None if i is None else self.names[i]
        self._notice_counts[(kind, joint)] += 1
        count = self._notice_counts[(kind, joint)]
        if count > MAX_NOTICES_PER_KIND:
            return
        if count == MAX_NOTICES_PER_KIND:
            message += f" (further {kind} notices are only counted in summary.json)"
        self.notices.append(SafetyNotice(tick, time_s, kind, joint, message))

    # --- 3. shape the command ------------------------------------------------------------------
    def command(self, controller_goal: np.ndarray | None, sample: JointSample) -> np.ndarray | None:
        """The goal to send this tick, or None to send nothing (torque off, or nothing known).

        Call after `observe` on the same tick. Whatever is returned lies within every joint's
        [min_angle_rad, max_angle_rad].
        """
        if self.state == SafeState.TORQUE_OFF:
            return None
        if self.state == SafeState.RUN:
            goal = controller_goal if controller_goal is not None else self._last_goal
            if goal is None:
                return None
            goal = np.asarray(goal, dtype=float)
            if goal.shape != self.min_goal.shape or not np.isfinite(goal).all():
                self._trip(
                    self._tick,
                    self._time_s,
                    "command_invalid",
                    None,
                    self.tuning.on_command_invalid,
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
        return goal.copy()

    def _limit(self, goal: np.ndarray) -> np.ndarray:
        clipped = np.clip(goal, self.min_goal, self.max_goal)
        at_limit = clipped != goal
        if at_limit.any():
            self._clipped_total += at_limit
            for i in np.flatnonzero(at_limit):
                self._notice(
                    self._tick,
                    self._time_s,
                    "goal_limited",
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
        # the last goal is inside the limits, so the rate-limited goal is too
        return limited

    def _safe_goal(self, sample: JointSample) -> np.ndarray | None:
        """Where to hold: the motor's present angle (the last goal where it is unknown);
        for back_off, moved away from the direction the motor current pushes."""
        last = self._last_goal if self._last_goal is not None else np.full(len(self.names), np.nan)
        base = np.where(sample.motor_valid, sample.motor_angle_rad, last)
        base = np.where(np.isfinite(base), base, last)
        if not np.isfinite(base).all():
            return None
        if self.state == SafeState.BACK_OFF:
            current = np.where(sample.motor_valid, sample.motor_current_a, 0.0)
            push = np.sign(np.nan_to_num(current))
            base = base - push * self.safety.current_guard_backoff_rad
        return np.clip(base, self.min_goal, self.max_goal)

    def set_current_limits(self, limits_a: np.ndarray) -> None:
        """The actuators' current caps [A] the overload guard compares against (the devices
        report them at open). NaN: unknown, the guard cannot act on that joint."""
        n = len(self.joints)
        limit = np.broadcast_to(np.asarray(limits_a, dtype=float), (n,)).copy()
        if np.any(limit <= 0):
            raise ValueError(f"current limits must be > 0 A, got {limit}")
        self.current_limit_a = limit

    def check_reference(self, reference_min: float, reference_max: float) -> None:
        """Refuse an experiment whose reference leaves a joint's limits (before anything moves)."""
        if not (math.isfinite(reference_min) and math.isfinite(reference_max)):
            raise ReferenceOutsideLimits(
                f"the reference spans [{reference_min}, {reference_max}] rad: not finite"
            )
        for joint in self.joints:
            if reference_min < joint.min_angle_rad or reference_max > joint.max_angle_rad:
                raise ReferenceOutsideLimits(
                    f"the reference spans [{reference_min:+.3f}, {reference_max:+.3f}] rad, "
                    f"beyond joint {joint.name!r}'s limits [{joint.min_angle_rad:+.3f}, "
                    f"{joint.max_angle_rad:+.3f}] rad: nothing was sent; shorten the "
                    "trajectory or widen min_angle_rad / max_angle_rad in the configuration"
                )
