"""The interface every controller offers the loop (`JointController`) and the parts of a goal
it reports (`ControlTerms`).

Conventions: reference_rad is the desired LINK angle theta_d; the output is the goal MOTOR angle
u for the actuator's position servo; angles in rad; arrays of length n.

Each tick the loop calls `step(theta_m, theta_j, theta_d)`, sends the goal (possibly clipped by
the supervisor), then `notify_applied(goal_sent)`: the DOB and the accumulation use what was
really sent (anti-windup). `reset` must come first and gives a bumpless start from the goal in
force (the hold or homing goal the servo was driven with; see `JointController.reset`). Calling
out of this order raises `ControllerUsageError`.
"""

from __future__ import annotations

import abc
from dataclasses import dataclass

import numpy as np

from controller.planned_motion import PlannedMotion


class ControllerUsageError(RuntimeError):
    """A controller was called out of order (step before reset, no notify_applied, ...)."""


@dataclass(frozen=True)
class ControlTerms:
    """One tick's parts of the goal, for the log: u = uc + d_hat + ug [rad, per joint].

    uc: LQR part (the reference itself for "pid" and "gc"); d_hat: the DOB's contribution to u
    (in the accumulated reading, its running sum); ug: gravity feed-forward (8); u: the goal
    (after notify_applied: what was sent). disturbance_estimate_rad: q(k), the Q-filtered
    estimate before Kdist (zero for controllers without DOB).
    """

    uc: np.ndarray
    d_hat: np.ndarray
    ug: np.ndarray
    u: np.ndarray
    disturbance_estimate_rad: np.ndarray


class JointController(abc.ABC):
    """One controller for n joints, stepped once per tick by the loop (see module docstring)."""

    name: str

    def __init__(self, n_joints: int) -> None:
        self.n_joints = n_joints
        self._phase = "needs_reset"

    def _joint_array(self, value: np.ndarray, what: str) -> np.ndarray:
        array = np.asarray(value, dtype=float)
        if array.shape != (self.n_joints,):
            raise ValueError(f"{what} must have shape ({self.n_joints},), got {array.shape}")
        if np.count_nonzero(np.isfinite(array)) != array.size:
            bad = np.flatnonzero(~np.isfinite(array)).tolist()
            raise ValueError(f"{what} is not finite for joints {bad}: do not step on invalid data")
        return array

    def reset(
        self,
        motor_angle_rad: np.ndarray,
        link_angle_rad: np.ndarray,
        reference_rad: np.ndarray,
        goal_in_force_rad: np.ndarray | None = None,
    ) -> None:
        """Bumpless start from the goal the servo is being driven with.

        goal_in_force_rad: the goal sent on the last tick before this controller takes over
        (the hold or homing goal). Under a load the servo rests short of its goal (by
        tau / k_s: gravity on the testbed, ~8 mrad), so the measured motor angle is NOT the goal
        in force; starting from it would step the goal by that lag. None: take the measured
        motor angle (only right when the servo rests exactly at its goal)."""
        motor = self._joint_array(motor_angle_rad, "motor_angle_rad")
        goal = (
            motor
            if goal_in_force_rad is None
            else self._joint_array(goal_in_force_rad, "goal_in_force_rad")
        )
        self._reset(
            motor,
            self._joint_array(link_angle_rad, "link_angle_rad"),
            self._joint_array(reference_rad, "reference_rad"),
            goal,
        )
        self._phase = "ready"

    def step(
        self, motor_angle_rad: np.ndarray, link_angle_rad: np.ndarray, reference_rad: np.ndarray
    ) -> np.ndarray:
        """One tick: measured angles and desired link angles in, goal motor angles out [rad]."""
        if self._phase != "ready":
            raise ControllerUsageError(
                f"{self.name}: step() called "
                + (
                    "before reset()"
                    if self._phase == "needs_reset"
                    else "again without notify_applied() for the previous goal"
                )
            )
        goal = self._step(
            self._joint_array(motor_angle_rad, "motor_angle_rad"),
            self._joint_array(link_angle_rad, "link_angle_rad"),
            self._joint_array(reference_rad, "reference_rad"),
        )
        self._phase = "awaiting_applied"
        return goal.copy()

    def resync(self, motor_angle_rad: np.ndarray, link_angle_rad: np.ndarray) -> None:
        """Before a step that follows a gap (ticks without a step: a skipped deadline, a failed
        read). The discrete model differences the samples over one period; without this the gap
        would read as one period's motion (the DOB would add a spike of ~(gap - 1) x velocity x
        dt / (Kp dt) for good in the accumulated reading). Call it with the angles the next
        step() gets; that step then holds the disturbance estimate and reads no increment."""
        if self._phase != "ready":
            raise ControllerUsageError(f"{self.name}: resync() is for between ticks, after reset()")
        self._resync(
            self._joint_array(motor_angle_rad, "motor_angle_rad"),
            self._joint_array(link_angle_rad, "link_angle_rad"),
        )

    @abc.abstractmethod
    def _resync(self, motor: np.ndarray, link: np.ndarray) -> None: ...

    def notify_applied(self, applied_goal_rad: np.ndarray) -> None:
        """The goal actually sent after the last step (clipped or not). Call after every step."""
        if self._phase != "awaiting_applied":
            raise ControllerUsageError(f"{self.name}: notify_applied() without a preceding step()")
        self._notify_applied(self._joint_array(applied_goal_rad, "applied_goal_rad"))
        self._phase = "ready"

    def set_kdist(self, kdist: np.ndarray | float) -> None:
        """Change the DOB gain per joint between ticks (only controllers with a DOB); the change
        ramps over ControllerParams.kdist_ramp_s."""
        raise ControllerUsageError(
            f"{self.name!r} has no disturbance observer; set_kdist needs 'gc+lqr+dob'"
        )

    def set_planned_motion(self, motion: PlannedMotion | None) -> None:  # noqa: B027
        """The plan's motion at the coming tick (controller/planned_motion.py), or None; only
        the LQR controllers use it (reference_feedforward). Call before `step`."""

    @property
    @abc.abstractmethod
    def terms(self) -> ControlTerms:
        """The last tick's parts (copies)."""

    @abc.abstractmethod
    def _reset(
        self, motor: np.ndarray, link: np.ndarray, reference: np.ndarray, goal: np.ndarray
    ) -> None: ...

    @abc.abstractmethod
    def _step(self, motor: np.ndarray, link: np.ndarray, reference: np.ndarray) -> np.ndarray: ...

    @abc.abstractmethod
    def _notify_applied(self, applied: np.ndarray) -> None: ...
