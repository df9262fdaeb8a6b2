"""State of (20) from quantised encoders at the loop rate: x = [theta_m; theta_j; dtheta_j].

Sensors: the actuator's motor encoder (quantum q_m) and the link encoder (quantum q_j). Their
resolutions are device facts: the caller passes them (the loop takes them from its drivers);
the analysis below is in terms of q. For scale, the testbed: q_m = 2 pi / 501,923 = 1.2518e-5 rad
(H54-200-S500-R), q_j = 2 pi / 983,040 = 6.392e-6 rad (RLS RLC2IC on an MR075 ring). Angles are
used as read.

What is fed back, said once. The derivative-form LQR (24) gets dx(k) = x(k) - x(k-1) with the
link velocity from the backward difference v(k) = (theta_j(k) - theta_j(k-1)) / dt, optionally
low-passed, v_f(k) = beta v_f(k-1) + (1 - beta) v(k), beta = exp(-2 pi fc dt): so the
link-velocity increment d dtheta_j(k) = v(k) - v(k-1) is a second difference of the link angle.
The lab's code fed ZERO for that increment (its d dtheta_j block was never filled): that is
`link_velocity_increment="zero"` (`LinkVelocityIncrement`); the default is "backward-difference".
Why the plain difference by default: it has only half a tick of lag, which the discrete LQR
tolerates (tests/controller/test_closed_loop.py includes it in the sampled loop), and at a fine
link resolution its noise is small. The noise, with eps the quantisation error of each sample
(|eps| <= q/2 when rounding, 0 <= eps < q when truncating; uniform, variance q^2/12):

    difference:  |noise| < q / dt                       rms q / (dt sqrt 6)
    low-passed:  |noise| < (1 - beta) q / dt            rms (1 - beta) q / (dt sqrt(6 (1 + beta)))

At 200 Hz and q_j = 6.39e-6 rad: 1.28e-3 rad/s worst case, 5.2e-4 rad/s rms. In the LQR the
velocity enters as the increment d dtheta_j, whose sum over ticks telescopes, so the goal carries
the velocity gain times this noise (not its integral): at most 0.33 rad/(rad/s) x 1.28e-3 rad/s =
4e-4 rad for a 2 kg m^2 link, much less for lighter ones (the gain falls with the inertia).

Deflection theta_j - theta_m (sign as `drivers.joint_bus.JointSample`): error < (q_m + q_j) / 2
(`deflection_error_bound_rad`; 9.5e-6 rad on the testbed, 0.019 N m of spring torque at
K = 2000 N m/rad).
"""

from __future__ import annotations

import enum
import math

import numpy as np


class LinkVelocityIncrement(enum.StrEnum):
    """The link velocity's increment in the LQR's state (see the module docstring)."""

    BACKWARD_DIFFERENCE = "backward-difference"
    ZERO = "zero"


LINK_VELOCITY_INCREMENTS: tuple[str, ...] = tuple(member.value for member in LinkVelocityIncrement)


def _velocity_filter_pole(cutoff_hz: float | None, dt_s: float) -> float:
    if cutoff_hz is None:
        return 0.0
    if not (np.isfinite(cutoff_hz) and cutoff_hz > 0):
        raise ValueError(f"link velocity cut-off must be None or > 0 Hz, got {cutoff_hz}")
    return math.exp(-2.0 * math.pi * cutoff_hz * dt_s)


def velocity_noise_bound_rad_s(
    resolution_rad: float, dt_s: float, cutoff_hz: float | None = None
) -> float:
    """Worst-case quantisation noise of the (filtered) difference velocity: (1 - beta) q / dt."""
    return (1.0 - _velocity_filter_pole(cutoff_hz, dt_s)) * resolution_rad / dt_s


def deflection_error_bound_rad(motor_resolution_rad: float, link_resolution_rad: float) -> float:
    """Worst-case quantisation error of theta_j - theta_m, both encoders rounding: (q_m + q_j)/2."""
    return 0.5 * (motor_resolution_rad + link_resolution_rad)


def velocity_noise_rms_rad_s(
    resolution_rad: float, dt_s: float, cutoff_hz: float | None = None
) -> float:
    """Rms quantisation noise for white uniform errors: (1 - beta) q / (dt sqrt(6 (1 + beta)))."""
    beta = _velocity_filter_pole(cutoff_hz, dt_s)
    return (1.0 - beta) * resolution_rad / (dt_s * math.sqrt(6.0 * (1.0 + beta)))


class FlexibleJointStateEstimator:
    """x(k) = [theta_m; theta_j; v_j] and dx(k) = x(k) - x(k-1) for n joints, stacked by quantity.

    link_velocity_increment: "backward-difference" (dx carries v(k) - v(k-1)) or "zero" (the
    lab's: the increment's velocity block is zero; the state keeps the estimated velocity).
    Arrays returned are owned by the estimator and overwritten by the next update.
    """

    def __init__(
        self,
        n_joints: int,
        dt_s: float,
        link_velocity_cutoff_hz: float | None = None,
        link_velocity_increment: LinkVelocityIncrement = "backward-difference",
    ) -> None:
        if not (np.isfinite(dt_s) and dt_s > 0):
            raise ValueError(f"dt_s must be finite and > 0, got {dt_s}")
        if link_velocity_increment not in LINK_VELOCITY_INCREMENTS:
            raise ValueError(
                f"link_velocity_increment must be one of {LINK_VELOCITY_INCREMENTS}, "
                f"got {link_velocity_increment!r}"
            )
        self.n_joints = n_joints
        self.dt_s = float(dt_s)
        self._zero_velocity_increment = link_velocity_increment == LinkVelocityIncrement.ZERO
        self._beta = _velocity_filter_pole(link_velocity_cutoff_hz, dt_s)
        self._state = np.zeros(3 * n_joints)
        self._previous_state = np.zeros(3 * n_joints)
        self._increment = np.zeros(3 * n_joints)
        self._link_step = np.zeros(n_joints)
        self._motor_velocity = np.zeros(n_joints)
        self._motor_velocity_increment = np.zeros(n_joints)

    @property
    def state(self) -> np.ndarray:
        return self._state

    @property
    def increment(self) -> np.ndarray:
        return self._increment

    @property
    def motor_velocity_increment(self) -> np.ndarray:
        """d omega_m(k) = omega_m(k) - omega_m(k-1), omega_m(k) = (theta_m(k) - theta_m(k-1)) / dt:
        the motor velocity's increment, for a design whose servo model has the motor velocity as
        a state (`controller.servo_cascade`)."""
        return self._motor_velocity_increment

    @property
    def link_velocity_rad_s(self) -> np.ndarray:
        return self._state[2 * self.n_joints :]

    @property
    def deflection_rad(self) -> np.ndarray:
        """theta_j - theta_m (positive when the load leads the motor)."""
        n = self.n_joints
        return self._state[n : 2 * n] - self._state[:n]

    def reset(self, motor_angle_rad: np.ndarray, link_angle_rad: np.ndarray) -> None:
        """Start at rest at the given angles (velocity 0, increment 0)."""
        n = self.n_joints
        self._state[:n] = motor_angle_rad
        self._state[n : 2 * n] = link_angle_rad
        self._state[2 * n :] = 0.0
        self._previous_state[:] = self._state
        self._increment[:] = 0.0
        self._motor_velocity[:] = 0.0
        self._motor_velocity_increment[:] = 0.0

    def resync(self, motor_angle_rad: np.ndarray, link_angle_rad: np.ndarray) -> None:
        """After a gap in the samples (a skipped tick, a failed read): take these angles as the
        previous sample, so that the next `update` (with the same angles) reads no motion
        instead of the whole gap's motion as one period's. The increments of that tick are zero;
        in the incremental LQR the next tick's catch up with the motion."""
        n = self.n_joints
        self._state[:n] = motor_angle_rad
        self._state[n : 2 * n] = link_angle_rad

    def update(self, motor_angle_rad: np.ndarray, link_angle_rad: np.ndarray) -> np.ndarray:
        """New sample: returns the state x(k); `increment` then holds dx(k)."""
        n = self.n_joints
        self._previous_state[:] = self._state
        np.subtract(link_angle_rad, self._previous_state[n : 2 * n], out=self._link_step)
        velocity = self._state[2 * n :]
        velocity *= self._beta
        velocity += ((1.0 - self._beta) / self.dt_s) * self._link_step
        self._state[:n] = motor_angle_rad
        self._state[n : 2 * n] = link_angle_rad
        np.subtract(self._state, self._previous_state, out=self._increment)
        # motor velocity by the difference of the motor encoder, and its increment
        self._motor_velocity_increment[:] = self._motor_velocity
        np.multiply(self._increment[:n], 1.0 / self.dt_s, out=self._motor_velocity)
        np.subtract(
            self._motor_velocity,
            self._motor_velocity_increment,
            out=self._motor_velocity_increment,
        )
        if self._zero_velocity_increment:
            self._increment[2 * n :] = 0.0
        return self._state
