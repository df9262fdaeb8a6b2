"""The safety supervisor: between the controller and the bus, every tick.

What it does each tick, in this order:
1. watch the sample (`observe`): the actuator's own protection (Hardware Error Status, read every
   tick through the indirect-mapped state block, or torque found off), the gear deflection
   |theta_m - theta_j|, the motor current held near its limit (a software overload guard that
   acts before the actuator's own protection trips), a stale or silent link encoder, bus failures
   (no valid reply from an actuator), loop overruns;
2. when a watch fires, latch the configured safe state for that cause and log it with the joint,
   the time and the figures (`events`);
3. shape the command (`command`): in normal running, clip each goal to the joint's limits and
   to the goal rate limit; in a safe state, replace it:
       hold        keep the motor where it was when the cause fired
       back_off    move the goal `current_guard_backoff_rad` away from the direction the motor
                   was pushing (relieves a load or a contact), then hold there
       torque_off  torque off on every joint, no more goals
   A later, more severe cause can escalate (hold -> back_off -> torque_off), never the reverse.
Recovery is never automatic: a latched safe state lasts until the run ends; clearing an
actuator's hardware error takes an explicit `hil reboot` or `hil run --reboot-first`.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from drivers.joint_bus import HardwareError, JointSample
from hil.config import JointConfig, SafetyConfig


class SafeState(enum.IntEnum):
    RUN = 0
    HOLD = 1
    BACK_OFF = 2
    TORQUE_OFF = 3

    @classmethod
    def from_reaction(cls, reaction: str) -> SafeState:
        return {"hold": cls.HOLD, "back_off": cls.BACK_OFF, "torque_off": cls.TORQUE_OFF}[reaction]


@dataclass(frozen=True)
class SafetyEvent:
    tick: int
    time_s: float
    cause: str  # hardware_error, torque_lost, deflection, current, link_stale, bus_error, overrun
    joint: str | None
    action: str  # hold, back_off, torque_off
    message: str


@dataclass
class _JointWatch:
    current_near_limit_s: float = 0.0
    link_bad_ticks: int = 0
    link_frozen_ticks: int = 0
    motor_bad_ticks: int = 0
    last_link_rad: float = math.nan
    motor_at_freeze_rad: float = math.nan


@dataclass
class Supervisor:
    safety: SafetyConfig
    joints: Sequence[JointConfig]
    period_s: float
    current_limit_a: np.ndarray  # the actuators' active current caps, for the guard
    state: SafeState = SafeState.RUN
    events: list[SafetyEvent] = field(default_factory=list)
    overruns: int = 0
    _watch: list[_JointWatch] = field(default_factory=list)
    _hold_goal: np.ndarray | None = None
    _last_goal: np.ndarray | None = None
    _expect_torque: bool = False

    def __post_init__(self) -> None:
        n = len(self.joints)
        self._watch = [_JointWatch() for _ in range(n)]
        self.min_goal = np.array([j.min_angle_rad for j in self.joints])
        self.max_goal = np.array([j.max_angle_rad for j in self.joints])
        self.current_limit_a = np.broadcast_to(np.asarray(self.current_limit_a, float), (n,))

    # --- lifecycle ---------------------------------------------------------------------------
    def torque_enabled(self, goal_rad: np.ndarray) -> None:
        """The loop turned torque on with this goal (the present motor angle)."""
        self._expect_torque = True
        self._last_goal = np.array(goal_rad, dtype=float)

    def torque_disabled(self) -> None:
        self._expect_torque = False

    @property
    def safe(self) -> bool:
        return self.state != SafeState.RUN

    def note_overrun(self, tick: int, time_s: float, skipped: int) -> None:
        self.overruns += 1
        if self.overruns > self.safety.overrun_limit:
            self._trip(
                tick,
                time_s,
                "overrun",
                None,
                self.safety.on_overrun,
                f"{self.overruns} loop overruns (limit {self.safety.overrun_limit}); "
                f"last one skipped {skipped} tick(s)",
            )

    # --- 1. watch ----------------------------------------------------------------------------
    def observe(self, tick: int, time_s: float, sample: JointSample) -> list[SafetyEvent]:
        """Run every watch on this tick's sample; returns the events it raised."""
        before = len(self.events)
        s = self.safety
        for i, joint in enumerate(self.joints):
            w = self._watch[i]
            name = joint.name
            if sample.motor_valid[i]:
                w.motor_bad_ticks = 0
                bits = int(sample.hardware_error[i])
                if bits:
                    self._trip(
                        tick,
                        time_s,
                        "hardware_error",
                        name,
                        s.on_hardware_error,
                        f"actuator {joint.dynamixel_id} reports Hardware Error Status 0x{bits:02X} "
                        f"({HardwareError.describe(bits)}); torque is "
                        f"{'on' if sample.torque_enabled[i] else 'off'}",
                    )
                elif self._expect_torque and not sample.torque_enabled[i]:
                    self._trip(
                        tick,
                        time_s,
                        "torque_lost",
                        name,
                        s.on_hardware_error,
                        f"actuator {joint.dynamixel_id} has torque off without a hardware error",
                    )
                self._watch_current(tick, time_s, i, abs(float(sample.motor_current_a[i])))
            else:
                w.motor_bad_ticks += 1
                if w.motor_bad_ticks >= s.bus_error_ticks:
                    errors = "; ".join(sample.bus_errors) or "no valid reply"
                    self._trip(
                        tick,
                        time_s,
                        "bus_error",
                        name,
                        s.on_bus_error,
                        f"actuator {joint.dynamixel_id}: {w.motor_bad_ticks} ticks without a valid "
                        f"reply ({errors})",
                    )
            self._watch_link(tick, time_s, i, sample)
            if sample.motor_valid[i] and sample.link_valid[i]:
                deflection = float(sample.link_angle_rad[i] - sample.motor_angle_rad[i])
                if abs(deflection) > s.max_deflection_rad:
                    self._trip(
                        tick,
                        time_s,
                        "deflection",
                        name,
                        s.on_deflection,
                        f"gear deflection {deflection:+.4f} rad beyond "
                        f"+-{s.max_deflection_rad} rad "
                        f"({abs(deflection) * joint.stiffness_nm_per_rad:.0f} N m at K)",
                    )
        return self.events[before:]

    def _watch_current(self, tick: int, time_s: float, i: int, current_a: float) -> None:
        s = self.safety
        w = self._watch[i]
        if not s.current_guard:
            return
        near = current_a >= s.current_guard_fraction * self.current_limit_a[i]
        w.current_near_limit_s = w.current_near_limit_s + self.period_s if near else 0.0
        if w.current_near_limit_s >= s.current_guard_time_s:
            self._trip(
                tick,
                time_s,
                "current",
                self.joints[i].name,
                s.on_current,
                f"motor current {current_a:.2f} A held above {s.current_guard_fraction:.0%} of "
                f"{self.current_limit_a[i]:.2f} A for {w.current_near_limit_s:.2f} s",
            )

    def _watch_link(self, tick: int, time_s: float, i: int, sample: JointSample) -> None:
        s = self.safety
        w = self._watch[i]
        name = self.joints[i].name
        if not sample.link_valid[i]:
            w.link_bad_ticks += 1
            if w.link_bad_ticks >= s.link_stale_ticks:
                self._trip(
                    tick,
                    time_s,
                    "link_stale",
                    name,
                    s.on_link_stale,
                    f"link encoder node {self.joints[i].encoder_node_id}: no fresh position for "
                    f"{w.link_bad_ticks} ticks (last {sample.link_age_s[i]:.3f} s ago)",
                )
            return
        w.link_bad_ticks = 0
        link = float(sample.link_angle_rad[i])
        motor = float(sample.motor_angle_rad[i])
        if link == w.last_link_rad:
            if w.link_frozen_ticks == 0:
                w.motor_at_freeze_rad = motor
            w.link_frozen_ticks += 1
            # A frozen reading while the motor turns far: a hung counter. A link blocked by an
            # obstacle also reads constant while the motor winds the gear up, so the motor must
            # have moved by half the deflection bound (a torque change of K x that) first.
            moved = abs(motor - w.motor_at_freeze_rad) if sample.motor_valid[i] else 0.0
            if w.link_frozen_ticks >= s.link_stale_ticks and moved > 0.5 * s.max_deflection_rad:
                self._trip(
                    tick,
                    time_s,
                    "link_stale",
                    name,
                    s.on_link_stale,
                    f"link encoder node {self.joints[i].encoder_node_id}: position frozen for "
                    f"{w.link_frozen_ticks} ticks while the motor moved {moved:.4f} rad",
                )
        else:
            w.link_frozen_ticks = 0
        w.last_link_rad = link

    def _trip(
        self, tick: int, time_s: float, cause: str, joint: str | None, reaction: str, message: str
    ) -> None:
        target = SafeState.from_reaction(reaction)
        already = any(e.cause == cause and e.joint == joint for e in self.events)
        if target <= self.state and already:
            return
        if target > self.state:
            self.state = target
        self.events.append(SafetyEvent(tick, time_s, cause, joint, reaction, message))

    # --- 3. shape the command ------------------------------------------------------------------
    def command(self, controller_goal: np.ndarray | None, sample: JointSample) -> np.ndarray | None:
        """The goal to send this tick, or None to send nothing (torque off)."""
        if self.state == SafeState.TORQUE_OFF:
            return None
        if self.state in (SafeState.HOLD, SafeState.BACK_OFF):
            if self._hold_goal is None:
                self._hold_goal = self._safe_goal(sample)
            goal = self._hold_goal
        else:
            goal = controller_goal if controller_goal is not None else self._last_goal
            if goal is None:
                return None
        goal = np.clip(goal, self.min_goal, self.max_goal)
        if self._last_goal is not None and self.state == SafeState.RUN:
            step = self.safety.max_goal_rate_rad_s * self.period_s
            goal = np.clip(goal, self._last_goal - step, self._last_goal + step)
        self._last_goal = np.array(goal, dtype=float)
        return self._last_goal

    def _safe_goal(self, sample: JointSample) -> np.ndarray:
        base = np.where(sample.motor_valid, sample.motor_angle_rad, self._last_goal)
        base = np.where(np.isfinite(base), base, self._last_goal)
        if self.state == SafeState.BACK_OFF:
            push = np.sign(np.nan_to_num(sample.motor_current_a))
            base = base - push * self.safety.current_guard_backoff_rad
        return np.array(base, dtype=float)

    def check_reference(self, reference_min: float, reference_max: float) -> None:
        """Refuse an experiment whose reference leaves a joint's limits (before anything moves)."""
        for joint in self.joints:
            if reference_min < joint.min_angle_rad or reference_max > joint.max_angle_rad:
                raise ValueError(
                    f"the reference spans [{reference_min:+.3f}, {reference_max:+.3f}] rad, beyond "
                    f"joint {joint.name!r}'s limits [{joint.min_angle_rad:+.3f}, "
                    f"{joint.max_angle_rad:+.3f}] rad"
                )
