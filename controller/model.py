"""The flexible-joint model of Kim et al., ICRA 2018, Sec. II and III-C, for n joints.

Each joint is a position-servoed motor driving its link through a spring-damper gear
(K, D, Kp diagonal, one entry per joint):

    (1)  tau_j = K (theta_m - theta_j) + D (dtheta_m - dtheta_j)   gear torque
    (4)  dtheta_m = Kp (u - theta_m)                                the servo, first order
    (19) ddtheta_j = Sm tau_j                                       the links (gravity compensated,
                                                                    Coriolis neglected: slow motion)

(2), the motor's own rigid-body equation, is replaced by (4): the paper treats the actuator's
position loop as a first-order lag from the goal angle u to the motor angle. (3) with the
gravity compensator of Sec. III-A and slow motion reduces to (19), where
Sm = S M^-1 (I - Pc) S^T (n x n); for the 1-DoF testbed Sm = 1 / I_link.

Substituting (4) into (1) and (1) into (19) gives the state space (20) with
x = [theta_m; theta_j; dtheta_j] stacked by quantity (3n), y = theta_j, input u:

    A = [[-Kp,            0,       0    ],      B = [[Kp      ],     C = [0, I, 0]
         [ 0,             0,       I    ],           [0       ],
         [Sm (K - D Kp), -Sm K,  -Sm D  ]]           [Sm D Kp ]]

Units: angles rad, velocities rad/s, K N m/rad, D N m s/rad, Kp 1/s, Sm 1/(kg m^2).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np
import scipy.linalg

# Sec. IV-A: "the actuator's spring coefficient K, damping coefficient D, and the proportional
# gain Kp in (4) were 2000, 100, and 10" (same for the testbed and for DYROS-JET).
PAPER_STIFFNESS_NM_PER_RAD = 2000.0
PAPER_DAMPING_NMS_PER_RAD = 100.0
PAPER_SERVO_GAIN_PER_S = 10.0


class Discretisation(enum.StrEnum):
    """How a continuous model is sampled: zero-order hold or forward Euler."""

    ZOH = "zoh"
    EULER = "euler"


DISCRETISATIONS: tuple[str, ...] = tuple(member.value for member in Discretisation)


def per_joint_array(value: object, what: str, n_joints: int | None = None) -> np.ndarray:
    """A read-only float array of length n from a scalar or a sequence; clear error otherwise."""
    array = np.array(value, dtype=float, ndmin=1)
    if array.ndim != 1:
        raise ValueError(
            f"{what} must be a scalar or a 1-D per-joint array, got shape {array.shape}"
        )
    if n_joints is not None:
        if array.size == 1:
            array = np.full(n_joints, array[0])
        elif array.size != n_joints:
            raise ValueError(f"{what} needs {n_joints} entries (one per joint), got {array.size}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{what} must be finite, got {array}")
    array.flags.writeable = False
    return array


@dataclass(frozen=True)
class FlexibleJointParams:
    """Per-joint gear and servo figures of (1) and (4), arrays of length n (read-only).

    stiffness_nm_per_rad: K > 0; damping_nms_per_rad: D >= 0; servo_gain_per_s: Kp > 0.
    """

    stiffness_nm_per_rad: np.ndarray
    damping_nms_per_rad: np.ndarray
    servo_gain_per_s: np.ndarray

    def __post_init__(self) -> None:
        stiffness = per_joint_array(self.stiffness_nm_per_rad, "stiffness_nm_per_rad")
        n = stiffness.size
        damping = per_joint_array(self.damping_nms_per_rad, "damping_nms_per_rad", n)
        servo_gain = per_joint_array(self.servo_gain_per_s, "servo_gain_per_s", n)
        if np.any(stiffness <= 0):
            raise ValueError(f"stiffness_nm_per_rad must be > 0 for every joint, got {stiffness}")
        if np.any(damping < 0):
            raise ValueError(f"damping_nms_per_rad must be >= 0 for every joint, got {damping}")
        if np.any(servo_gain <= 0):
            raise ValueError(f"servo_gain_per_s must be > 0 for every joint, got {servo_gain}")
        object.__setattr__(self, "stiffness_nm_per_rad", stiffness)
        object.__setattr__(self, "damping_nms_per_rad", damping)
        object.__setattr__(self, "servo_gain_per_s", servo_gain)

    @property
    def n_joints(self) -> int:
        return int(self.stiffness_nm_per_rad.size)

    @classmethod
    def uniform(
        cls,
        n_joints: int,
        stiffness_nm_per_rad: float = PAPER_STIFFNESS_NM_PER_RAD,
        damping_nms_per_rad: float = PAPER_DAMPING_NMS_PER_RAD,
        servo_gain_per_s: float = PAPER_SERVO_GAIN_PER_S,
    ) -> FlexibleJointParams:
        """n identical joints; the defaults are the paper's (Sec. IV-A)."""
        if n_joints < 1:
            raise ValueError(f"n_joints must be >= 1, got {n_joints}")
        return cls(
            stiffness_nm_per_rad=np.full(n_joints, float(stiffness_nm_per_rad)),
            damping_nms_per_rad=np.full(n_joints, float(damping_nms_per_rad)),
            servo_gain_per_s=np.full(n_joints, float(servo_gain_per_s)),
        )

    def joint(self, index: int) -> FlexibleJointParams:
        """The parameters of one joint as a 1-joint set."""
        return FlexibleJointParams(
            stiffness_nm_per_rad=self.stiffness_nm_per_rad[index : index + 1],
            damping_nms_per_rad=self.damping_nms_per_rad[index : index + 1],
            servo_gain_per_s=self.servo_gain_per_s[index : index + 1],
        )


def single_link_sm(link_inertia_kg_m2: float) -> np.ndarray:
    """Sm of (19) for the 1-DoF testbed: 1 / I_link, as a 1 x 1 matrix [1/(kg m^2)]."""
    if not (np.isfinite(link_inertia_kg_m2) and link_inertia_kg_m2 > 0):
        raise ValueError(f"link_inertia_kg_m2 must be finite and > 0, got {link_inertia_kg_m2}")
    return np.array([[1.0 / link_inertia_kg_m2]])


def validate_sm(sm: np.ndarray, n_joints: int) -> np.ndarray:
    """Check Sm of (19): n x n, finite, symmetric, positive diagonal. Returns a float copy.

    Sm = S M^-1 (I - Pc) S^T is symmetric positive semi-definite; a non-positive diagonal
    entry would mean a joint that its own torque cannot accelerate.
    """
    matrix = np.array(sm, dtype=float, ndmin=2)
    if matrix.shape != (n_joints, n_joints):
        raise ValueError(
            f"sm must be {n_joints} x {n_joints} (one row/column per joint), got {matrix.shape}"
        )
    if not np.all(np.isfinite(matrix)):
        raise ValueError("sm must be finite")
    scale = max(1.0, float(np.max(np.abs(matrix))))
    if not np.allclose(matrix, matrix.T, rtol=0.0, atol=1e-9 * scale):
        raise ValueError("sm must be symmetric (it is S M^-1 (I - Pc) S^T)")
    if np.any(np.diag(matrix) <= 0):
        raise ValueError(f"sm must have a positive diagonal, got {np.diag(matrix)}")
    return matrix


@dataclass(frozen=True)
class StateSpace:
    """dx/dt = a x + b u, y = c x (continuous time)."""

    a: np.ndarray
    b: np.ndarray
    c: np.ndarray


@dataclass(frozen=True)
class DiscreteStateSpace:
    """x(k+1) = a x(k) + b u(k), y(k) = c x(k), at period dt_s, by `method`."""

    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    dt_s: float
    method: str


def flexible_joint_state_space(params: FlexibleJointParams, sm: np.ndarray) -> StateSpace:
    """The state space (20) for n joints; x = [theta_m; theta_j; dtheta_j], y = theta_j."""
    n = params.n_joints
    sm = validate_sm(sm, n)
    k = np.diag(params.stiffness_nm_per_rad)
    d = np.diag(params.damping_nms_per_rad)
    kp = np.diag(params.servo_gain_per_s)
    zero = np.zeros((n, n))
    eye = np.eye(n)
    a = np.block(
        [
            [-kp, zero, zero],
            [zero, zero, eye],
            [sm @ (k - d @ kp), -sm @ k, -sm @ d],
        ]
    )
    b = np.vstack([kp, zero, sm @ d @ kp])
    c = np.hstack([zero, eye, zero])
    return StateSpace(a=a, b=b, c=c)


def discretise(
    system: StateSpace, dt_s: float, method: Discretisation = "zoh"
) -> DiscreteStateSpace:
    """Sample a continuous system at dt_s.

    "zoh": exact for an input held constant over each period (what a goal angle written once a
    tick is): [[Ad, Bd], [0, I]] = expm([[A, B], [0, 0]] dt).
    "euler": forward Euler, Ad = I + A dt, Bd = B dt (the lab's code: psh117/dyros_jet,
    walking_controller.cpp, discreteModel).
    It misplaces every pole lambda with |1 + lambda dt| > 1 outside the unit circle: for one
    joint with Sm = 1/I the gear's fast real pole crosses -2/dt when I < D dt/2 - K dt^2/4
    (0.2375 kg m^2 for the paper's K, D at 200 Hz), and the Euler model is then unstable although
    the plant is not.
    """
    if not (np.isfinite(dt_s) and dt_s > 0):
        raise ValueError(f"dt_s must be finite and > 0, got {dt_s}")
    n_states, n_inputs = system.b.shape
    if method == Discretisation.ZOH:
        block = np.zeros((n_states + n_inputs, n_states + n_inputs))
        block[:n_states, :n_states] = system.a
        block[:n_states, n_states:] = system.b
        exponential = scipy.linalg.expm(block * dt_s)
        a_d = exponential[:n_states, :n_states]
        b_d = exponential[:n_states, n_states:]
    elif method == Discretisation.EULER:
        a_d = np.eye(n_states) + system.a * dt_s
        b_d = system.b * dt_s
    else:
        raise ValueError(f"discretisation must be one of {DISCRETISATIONS}, got {method!r}")
    return DiscreteStateSpace(a=a_d, b=b_d, c=system.c.copy(), dt_s=float(dt_s), method=method)


def joint_torque_nm(
    params: FlexibleJointParams,
    motor_angle_rad: np.ndarray,
    link_angle_rad: np.ndarray,
    motor_velocity_rad_s: np.ndarray,
    link_velocity_rad_s: np.ndarray,
) -> np.ndarray:
    """(1): tau_j = K (theta_m - theta_j) + D (dtheta_m - dtheta_j) [N m], per joint."""
    return params.stiffness_nm_per_rad * (
        np.asarray(motor_angle_rad) - link_angle_rad
    ) + params.damping_nms_per_rad * (np.asarray(motor_velocity_rad_s) - link_velocity_rad_s)
