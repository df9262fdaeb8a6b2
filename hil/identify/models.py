"""The flexible joint's equations as the fit simulates them (see the package docstring).

Three models, one per thing identified:

- `link_response`: the link behind the gear, driven by the measured motor motion,
      I theta_j'' = K (theta_m - theta_j + delta_0) + D (theta_m' - theta_j') - g m r cos theta_j
  ((1) and the 1-DoF (3)/(19)), discretised exactly over each period with the motor angle
  between samples the cubic Hermite curve through the measured angles and velocities, and the
  gravity term (taken at the measured link angle) linear between samples.
- `first_order_response`: the paper's servo model (4), theta_m' = Kp (u - theta_m), exact
  for the goal held over each period (zero-order hold).
- `advance`: the actuator's cascade and the two bodies, in physics steps h inside each period:
      w*   = clip(Kpp (u - theta_m), +-w_max)                     position loop -> speed command
      tau  = clip(kv (w* - theta_m') + iota, +-tau_max)           velocity PI   -> motor torque
      iota' = kv/Ti (w* - theta_m')   (not while clipped and winding further)
      Jm theta_m'' = tau - b theta_m' - F_c sgn(theta_m') - tau_j,  tau_j the gear torque (1)
      I  theta_j'' = tau_j - g m r cos theta_j
  stepped like MuJoCo's `implicitfast` (velocity-dependent forces implicit, positions
  semi-implicit) with Coulomb friction as a velocity-level impulse bounded by h F_c (the motor
  sticks when that suffices to stop it). The current the actuator reports is tau / Kt of the
  last physics step of the period.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.signal

from hil.identify.records import JointLog, KnownJointFigures


@dataclass(frozen=True)
class GearParams:
    """(1): tau_j = K (theta_m - theta_j + delta_0) + D (theta_m' - theta_j').

    deflection_offset_rad (delta_0): the deflection theta_j - theta_m the encoders read with no
    torque in the gear (their zero offsets); 0 for perfectly calibrated encoders.
    """

    stiffness_nm_per_rad: float
    damping_nms_per_rad: float
    deflection_offset_rad: float = 0.0

    def __post_init__(self) -> None:
        for name in self.__dataclass_fields__:  # plain floats: the scalar model is faster
            object.__setattr__(self, name, float(getattr(self, name)))


@dataclass(frozen=True)
class ServoParams:
    """The actuator's cascade: position P gain, velocity PI (gain, integral time).

    integral_initial_nm: the velocity loop's integral (a torque) at the first sample (0 when
    the log starts as torque is switched on).
    """

    position_gain_per_s: float
    velocity_gain_nms_per_rad: float
    velocity_integral_time_s: float
    integral_initial_nm: float = 0.0

    def __post_init__(self) -> None:
        for name in self.__dataclass_fields__:  # plain floats: the scalar model is faster
            object.__setattr__(self, name, float(getattr(self, name)))


@dataclass(frozen=True)
class MotorParams:
    """The motor side at the output: reflected rotor inertia, viscous and Coulomb friction."""

    reflected_inertia_kg_m2: float
    viscous_friction_nms_per_rad: float
    coulomb_friction_nm: float

    def __post_init__(self) -> None:
        for name in self.__dataclass_fields__:  # plain floats: the scalar model is faster
            object.__setattr__(self, name, float(getattr(self, name)))


@dataclass
class JointState:
    """Motor, link and servo-integral state; each entry a float or an array of them."""

    motor_angle_rad: np.ndarray | float
    motor_velocity_rad_s: np.ndarray | float
    link_angle_rad: np.ndarray | float
    link_velocity_rad_s: np.ndarray | float
    integral_nm: np.ndarray | float


# ----------------------------------------------------------------------------- helpers


def hermite_taylor(log: JointLog) -> np.ndarray:
    """Per period k, [p, p', p'', p'''] at its start of the cubic through theta_m and omega.

    The cubic p(s), 0 <= s <= T, has p(0) = theta_k, p'(0) = omega_k, p(T) = theta_k+1,
    p'(T) = omega_k+1. Shape (N-1, 4).
    """
    period = log.period_s
    theta, omega = log.motor_angle_rad, log.motor_velocity_rad_s
    rise = (theta[1:] - theta[:-1]) / period
    second = (6 * rise - 4 * omega[:-1] - 2 * omega[1:]) / period
    third = (-12 * rise + 6 * (omega[:-1] + omega[1:])) / period**2
    return np.stack([theta[:-1], omega[:-1], second, third], axis=1)


def goal_integral(log: JointLog) -> np.ndarray:
    """E_k = integral from t_0 to t_k of (u - theta_m) dt, exact for the held goal and the
    Hermite motor curve: per period T u_k - (T/2)(theta_k + theta_k+1) - (T^2/12)(w_k - w_k+1)."""
    period = log.period_s
    theta, omega, goal = log.motor_angle_rad, log.motor_velocity_rad_s, log.goal_rad
    per_period = (
        period * goal[:-1]
        - 0.5 * period * (theta[:-1] + theta[1:])
        - period**2 / 12 * (omega[:-1] - omega[1:])
    )
    return np.concatenate([[0.0], np.cumsum(per_period)])


def link_velocity_estimate(log: JointLog) -> np.ndarray:
    """The link's velocity from its encoder: five-point central differences (error O(T^4))."""
    angle, period = log.link_angle_rad, log.period_s
    velocity = np.gradient(angle, period)
    velocity[2:-2] = (8 * (angle[3:-1] - angle[1:-3]) - (angle[4:] - angle[:-4])) / (12 * period)
    return velocity


def propagate(transition: np.ndarray, drive: np.ndarray, initial: np.ndarray) -> np.ndarray:
    """States of x[k+1] = transition x[k] + drive[k] for k = 0..N-2, x[0] = initial.

    drive: (N-1, n). Returns (N, n). Runs as n^2 IIR filters (scipy.signal.lfilter), which is
    exact for this recursion and fast.
    """
    n = transition.shape[0]
    forcing = np.array(drive, dtype=float)
    forcing[0] += transition @ initial
    states = np.empty((forcing.shape[0] + 1, n))
    states[0] = initial
    padded = np.vstack([forcing, np.zeros((1, n))])
    states[1:] = 0.0
    for j in range(n):
        numerators, denominator = scipy.signal.ss2tf(
            transition, np.eye(n)[:, [j]], np.eye(n), np.zeros((n, 1))
        )
        for i in range(n):
            states[1:, i] += scipy.signal.lfilter(numerators[i], denominator, padded[:, j])[1:]
    return states


# ----------------------------------------------------------------------------- the link


@dataclass(frozen=True)
class LinkTrajectory:
    angle_rad: np.ndarray
    velocity_rad_s: np.ndarray


def link_response(log: JointLog, gear: GearParams, known: KnownJointFigures) -> LinkTrajectory:
    """The link's motion under (1) and (19) given the measured motor motion.

    Starts from the measured link angle and its estimated velocity at the first sample.
    """
    period = log.period_s
    inertia = known.link_inertia_kg_m2
    k, d = gear.stiffness_nm_per_rad, gear.damping_nms_per_rad
    # augmented state: [theta_j, theta_j', p, p', p'', p''', g, g', 1], g = cos(theta_j measured)
    m = np.zeros((9, 9))
    m[0, 1] = 1.0
    m[1, 0], m[1, 1] = -k / inertia, -d / inertia
    m[1, 2], m[1, 3] = k / inertia, d / inertia
    m[1, 6] = -known.gravity_torque_nm / inertia
    m[1, 8] = k * gear.deflection_offset_rad / inertia
    m[2, 3] = m[3, 4] = m[4, 5] = 1.0
    m[6, 7] = 1.0
    e = scipy.linalg.expm(m * period)
    cosine = np.cos(log.link_angle_rad)
    inputs = np.column_stack(
        [
            hermite_taylor(log),
            cosine[:-1],
            np.diff(cosine) / period,
            np.ones(len(log) - 1),
        ]
    )
    drive = inputs @ e[:2, 2:].T
    initial = np.array([log.link_angle_rad[0], link_velocity_estimate(log)[0]])
    states = propagate(e[:2, :2], drive, initial)
    return LinkTrajectory(states[:, 0], states[:, 1])


# ----------------------------------------------------------------------------- servo (4)


def first_order_response(
    goal_rad: np.ndarray, initial_rad: float, servo_gain_per_s: float, period_s: float
) -> np.ndarray:
    """(4) with the goal held over each period: theta[k+1] = a theta[k] + (1 - a) u[k],
    a = exp(-Kp T). Returns theta[0..N-1] for goals u[0..N-1] (the last goal is unused)."""
    a = math.exp(-servo_gain_per_s * period_s)
    out = np.empty(len(goal_rad))
    out[0] = initial_rad
    out[1:] = scipy.signal.lfilter([1 - a], [1.0, -a], goal_rad[:-1], zi=[a * initial_rad])[0]
    return out


# ----------------------------------------------------------------------------- the cascade


def integral_from_log(
    log: JointLog, servo: ServoParams, torque_cap_nm: float = math.inf
) -> np.ndarray:
    """The velocity loop's integral at each sample, from the measured signals.

    iota(t) = iota_0 + kv/Ti * integral(Kpp (u - theta_m) - theta_m') dt
            = iota_0 + kv/Ti * (Kpp E(t) - (theta_m(t) - theta_m(t_0)))
    With a finite torque cap, the anti-windup of `advance` is applied per period, judged at
    the period's start from the measured state: a period that starts clipped and winding
    further adds nothing, and the integral stays within the cap.
    """
    kv = servo.velocity_gain_nms_per_rad
    rate = kv / servo.velocity_integral_time_s
    travelled = log.motor_angle_rad - log.motor_angle_rad[0]
    increments = servo.position_gain_per_s * np.diff(goal_integral(log)) - np.diff(travelled)
    if not math.isfinite(torque_cap_nm):
        return servo.integral_initial_nm + rate * np.concatenate([[0.0], np.cumsum(increments)])
    speed_error = (
        servo.position_gain_per_s * (log.goal_rad - log.motor_angle_rad) - log.motor_velocity_rad_s
    ).tolist()
    steps = (rate * increments).tolist()
    integral = [float(servo.integral_initial_nm)]
    value = integral[0]
    for k, step in enumerate(steps):
        unclipped = kv * speed_error[k] + value
        if abs(unclipped) < torque_cap_nm or unclipped * speed_error[k] < 0:
            value = min(max(value + step, -torque_cap_nm), torque_cap_nm)
        integral.append(value)
    return np.array(integral)


class _ArrayOps:
    """Element-wise operations of `advance` on numpy arrays (many states at once)."""

    where = staticmethod(np.where)
    clip = staticmethod(np.clip)
    cos = staticmethod(np.cos)
    sign = staticmethod(np.sign)


class _ScalarOps:
    """The same on Python floats (one state: the free-running simulation, ~10x faster)."""

    @staticmethod
    def where(condition: bool, a: float, b: float) -> float:
        return a if condition else b

    @staticmethod
    def clip(x: float, low: float, high: float) -> float:
        return min(max(x, low), high)

    cos = staticmethod(math.cos)

    @staticmethod
    def sign(x: float) -> float:
        return float(x > 0) - float(x < 0)


def advance(
    state: JointState,
    goal_rad: np.ndarray | float,
    gear: GearParams,
    servo: ServoParams,
    motor: MotorParams,
    known: KnownJointFigures,
    period_s: float,
    physics_step_s: float,
) -> tuple[JointState, np.ndarray | float]:
    """One loop period of the cascade and the two bodies (module docstring), element-wise
    over arrays of states (or on one state of floats).

    Returns the state at the period's end and the current the actuator reports then (the
    torque of its last physics step over the torque constant).
    """
    ops = _ScalarOps if isinstance(state.motor_angle_rad, float) else _ArrayOps
    steps = max(1, round(period_s / physics_step_s))
    h = period_s / steps
    kpp, kv = servo.position_gain_per_s, servo.velocity_gain_nms_per_rad
    rate = kv / servo.velocity_integral_time_s
    k, d = gear.stiffness_nm_per_rad, gear.damping_nms_per_rad
    offset = gear.deflection_offset_rad
    jm, inertia = motor.reflected_inertia_kg_m2, known.link_inertia_kg_m2
    viscous, coulomb = motor.viscous_friction_nms_per_rad, motor.coulomb_friction_nm
    torque_cap = known.current_limit_torque_nm
    speed_cap = known.velocity_limit_rad_s or math.inf
    gravity = known.gravity_torque_nm
    # (M + h B)^-1 with B the velocity-dependent forces' negative Jacobian (implicit step)
    m11, m12, m22 = jm + h * (kv + viscous + d), -h * d, inertia + h * d
    det = m11 * m22 - m12 * m12
    i11, i12, i22 = m22 / det, -m12 / det, m11 / det
    q1, v1 = state.motor_angle_rad, state.motor_velocity_rad_s
    q2, v2 = state.link_angle_rad, state.link_velocity_rad_s
    integral = state.integral_nm
    torque = 0.0 * q1
    for _ in range(steps):
        speed_command = ops.clip(kpp * (goal_rad - q1), -speed_cap, speed_cap)
        speed_error = speed_command - v1
        unclipped = kv * speed_error + integral
        winds = (abs(unclipped) < torque_cap) | (unclipped * speed_error < 0)
        integral = ops.where(winds, integral + rate * speed_error * h, integral)
        integral = ops.clip(integral, -torque_cap, torque_cap)
        torque = ops.clip(kv * speed_error + integral, -torque_cap, torque_cap)
        gear_torque = k * (q1 - q2 + offset) + d * (v1 - v2)
        f1 = torque - viscous * v1 - gear_torque
        f2 = gear_torque - gravity * ops.cos(q2)
        v1_free = v1 + h * (i11 * f1 + i12 * f2)
        v2_free = v2 + h * (i12 * f1 + i22 * f2)
        # Coulomb friction: the impulse that stops the motor, if it is within h F_c
        stop_impulse = -v1_free / i11
        impulse = ops.where(
            abs(stop_impulse) <= h * coulomb, stop_impulse, -ops.sign(v1_free) * h * coulomb
        )
        v1 = v1_free + i11 * impulse
        v2 = v2_free + i12 * impulse
        q1 = q1 + h * v1
        q2 = q2 + h * v2
    current = torque / known.torque_constant_nm_per_a
    return JointState(q1, v1, q2, v2, integral), current


@dataclass(frozen=True)
class JointTrajectory:
    """A free-running simulation of the whole joint at the log's samples."""

    motor_angle_rad: np.ndarray
    motor_velocity_rad_s: np.ndarray
    link_angle_rad: np.ndarray
    motor_current_a: np.ndarray


def simulate_joint(
    log: JointLog,
    gear: GearParams,
    servo: ServoParams,
    motor: MotorParams,
    known: KnownJointFigures,
    physics_step_s: float,
) -> JointTrajectory:
    """The model driven by the logged goals alone, from the first sample's measured state."""
    n = len(log)
    out = np.empty((n, 4))
    state = JointState(
        float(log.motor_angle_rad[0]),
        float(log.motor_velocity_rad_s[0]),
        float(log.link_angle_rad[0]),
        float(link_velocity_estimate(log)[0]),
        float(servo.integral_initial_nm),
    )
    out[0] = [
        log.motor_angle_rad[0],
        log.motor_velocity_rad_s[0],
        log.link_angle_rad[0],
        log.motor_current_a[0],
    ]
    goals = log.goal_rad.tolist()
    for index in range(n - 1):
        state, current = advance(
            state, goals[index], gear, servo, motor, known, log.period_s, physics_step_s
        )
        out[index + 1] = (
            state.motor_angle_rad,
            state.motor_velocity_rad_s,
            state.link_angle_rad,
            current,
        )
    return JointTrajectory(out[:, 0], out[:, 1], out[:, 2], out[:, 3])
