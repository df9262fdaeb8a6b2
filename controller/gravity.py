"""Gravity compensator, Kim et al., ICRA 2018, Sec. III-A, (5)-(8).

The compensator is a feed-forward: the joint must carry the gravity torque tau_g, so the goal
is sent ahead of the desired link angle by the joint's static deflection under that load

    (8)  ug = K^-1 tau_g          the paper: the gear spring's deflection ("gear")
         ug = C tau_g             C the joint's whole static compliance ("joint", `GcCompliance`)

At rest (1) reads K (theta_m - theta_j) = tau_g(theta_j); with theta_m = theta_d + tau_g(theta_d)/K
the link sits exactly at theta_d (the link angle theta_j = theta_d solves the statics). The paper
can take theta_m = u because its servo model (4) has unit DC gain: a position servo that holds
any load without lag. A real position servo does not: the H54's cascade (position gain Kpp,
velocity PI kv, Ti) holds a load tau with the motor short of its goal by tau / (Kpp kv) until
its velocity integral winds the lag out over Ti (15 s at the stock registers). On the time scale
of a step the goal must therefore lead the link by

    C tau_g,   C = 1/K + 1/(Kpp kv)   (`joint_static_compliance`)

(derivation: at rest dtheta_m = 0 and, before the integral has grown, the servo's torque
kv Kpp (u - theta_m) equals the gear's K (theta_m - theta_j) = tau_g). Over times long against
Ti the integral removes the servo's part and "joint" over-compensates by tau_g / (Kpp kv);
"gear" is then exact. Which reading runs is `[controller] gc_compliance` (hil).

tau_g is evaluated at the REFERENCE (desired link) angle, as the lab's code does: a pure
feed-forward, free of encoder noise and of the extra loop (gravity's negative stiffness) that
evaluating it at the measured angle would close; in the static hold both coincide.

Humanoid (later, pinocchio): (5) tau_g = Jr' fr + Jl' fl with the support forces split by (6)-(7),
fr = mu f, fl = (1 - mu) f, mu = |p_com - p_l| / |p_r - p_l| (see `support_force_split`).
A `GravityModel` subclass returns that tau_g for the leg joints.

1-DoF testbed: `PendulumGravity`, the link swinging in a vertical plane; link angle 0 =
horizontal, positive = raising the load; the holding torque is tau_g = m g r cos(theta).
"""

from __future__ import annotations

import abc
import enum

import numpy as np

STANDARD_GRAVITY_M_S2 = 9.81


class GravityModel(abc.ABC):
    """tau_g(theta_j): the joint torques [N m] that hold the links still at these angles."""

    @abc.abstractmethod
    def gravity_torque(self, link_angle_rad: np.ndarray) -> np.ndarray:
        """Holding torque per joint [N m] at the given link angles [rad] (arrays of length n)."""


class NoGravity(GravityModel):
    """No gravity load (horizontal joints, or gravity carried elsewhere): tau_g = 0."""

    def gravity_torque(self, link_angle_rad: np.ndarray) -> np.ndarray:
        return np.zeros(np.shape(link_angle_rad))


class PendulumGravity(GravityModel):
    """Independent pendulum links: tau_g = m g r cos(theta) per joint [N m].

    mass_kg and com_distance_m are scalars (one joint) or per-joint sequences; the link's
    centre of mass is com_distance_m from the joint axis; theta = 0 is horizontal.
    """

    def __init__(
        self,
        mass_kg: float | np.ndarray,
        com_distance_m: float | np.ndarray,
        gravity_m_s2: float = STANDARD_GRAVITY_M_S2,
    ) -> None:
        mass = np.array(mass_kg, dtype=float, ndmin=1)
        distance = np.array(com_distance_m, dtype=float, ndmin=1)
        if mass.ndim != 1 or distance.shape != mass.shape:
            raise ValueError(
                f"mass_kg and com_distance_m must be scalars or equal-length 1-D arrays, got "
                f"shapes {mass.shape} and {distance.shape}"
            )
        if np.any(~np.isfinite(mass)) or np.any(mass < 0):
            raise ValueError(f"mass_kg must be finite and >= 0, got {mass}")
        if np.any(~np.isfinite(distance)) or np.any(distance < 0):
            raise ValueError(f"com_distance_m must be finite and >= 0, got {distance}")
        if not (np.isfinite(gravity_m_s2) and gravity_m_s2 >= 0):
            raise ValueError(f"gravity_m_s2 must be finite and >= 0, got {gravity_m_s2}")
        self.mass_kg = mass
        self.com_distance_m = distance
        self.gravity_m_s2 = float(gravity_m_s2)
        self._amplitude_nm = mass * distance * self.gravity_m_s2

    @property
    def n_joints(self) -> int:
        return int(self._amplitude_nm.size)

    def gravity_torque(self, link_angle_rad: np.ndarray) -> np.ndarray:
        return self._amplitude_nm * np.cos(link_angle_rad)


class GcCompliance(enum.StrEnum):
    """Which compliance C the gravity compensator offsets, ug = C tau_g (module docstring)."""

    JOINT = "joint"  # the gear in series with the position servo: 1/K + 1/(Kpp kv)
    GEAR = "gear"  # the paper's literal K^-1 (its servo model (4) holds any load without lag)


GC_COMPLIANCES: tuple[str, ...] = tuple(choice.value for choice in GcCompliance)


def servo_static_stiffness(
    position_gain_per_s: np.ndarray | float, velocity_gain_nms_per_rad: np.ndarray | float
) -> np.ndarray:
    """Kpp kv [N m/rad]: the torque a position servo with a P position loop over a velocity
    loop of proportional gain kv returns per radian of lag at rest, before its velocity
    integral has grown (the H54 at its default registers: 10 1/s x 78.5 N m s/rad = 785)."""
    gain = np.asarray(position_gain_per_s, dtype=float)
    velocity = np.asarray(velocity_gain_nms_per_rad, dtype=float)
    if np.any(~np.isfinite(gain)) or np.any(gain <= 0):
        raise ValueError(f"position_gain_per_s must be finite and > 0, got {gain}")
    if np.any(~np.isfinite(velocity)) or np.any(velocity <= 0):
        raise ValueError(f"velocity_gain_nms_per_rad must be finite and > 0, got {velocity}")
    return gain * velocity


def joint_static_compliance(
    gear_stiffness_nm_per_rad: np.ndarray | float,
    position_gain_per_s: np.ndarray | float,
    velocity_gain_nms_per_rad: np.ndarray | float,
) -> np.ndarray:
    """C = 1/K + 1/(Kpp kv) [rad/N m]: the gear spring in series with the servo's static
    stiffness (`servo_static_stiffness`); per joint. E.g. 1/2000 + 1/785 = 0.00177."""
    gear = np.asarray(gear_stiffness_nm_per_rad, dtype=float)
    if np.any(~np.isfinite(gear)) or np.any(gear <= 0):
        raise ValueError(f"gear_stiffness_nm_per_rad must be finite and > 0, got {gear}")
    return 1.0 / gear + 1.0 / servo_static_stiffness(position_gain_per_s, velocity_gain_nms_per_rad)


class GravityCompensator:
    """(8): ug = C tau_g(theta_d) [rad], the goal's lead that makes the joint hold the load.

    compliance_rad_per_nm: C per joint; the paper's K^-1 (`1 / stiffness`) or the whole joint's
    (`joint_static_compliance`).
    """

    def __init__(self, model: GravityModel, compliance_rad_per_nm: np.ndarray) -> None:
        compliance = np.array(compliance_rad_per_nm, dtype=float, ndmin=1)
        if np.any(~np.isfinite(compliance)) or np.any(compliance <= 0):
            raise ValueError(f"compliance_rad_per_nm must be finite and > 0, got {compliance}")
        self.model = model
        self._compliance_rad_per_nm = compliance

    @property
    def compliance_rad_per_nm(self) -> np.ndarray:
        return self._compliance_rad_per_nm.copy()

    def input_rad(self, reference_rad: np.ndarray) -> np.ndarray:
        """ug for the desired link angles (feed-forward, evaluated at the reference)."""
        return self.model.gravity_torque(reference_rad) * self._compliance_rad_per_nm


def support_force_split(
    com_position_m: np.ndarray,
    left_foot_position_m: np.ndarray,
    right_foot_position_m: np.ndarray,
    total_weight_n: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """(6)-(7): fr = mu f, fl = (1 - mu) f.

    mu is the CoM's position between the feet, projected on the line from the left to the right
    foot and clipped to [0, 1] (the paper's |p_com - p_l| / |p_r - p_l| when the CoM lies on that
    line; the lab's code uses the lateral distances, which is this projection for feet side by
    side). mu = 0: left single support; mu = 1: right single support.
    """
    left = np.asarray(left_foot_position_m, dtype=float)
    across = np.asarray(right_foot_position_m, dtype=float) - left
    span_sq = float(across @ across)
    if span_sq <= 0.0:
        raise ValueError("the feet are at the same position: the force split (7) is undefined")
    mu = float(np.clip((np.asarray(com_position_m, dtype=float) - left) @ across / span_sq, 0, 1))
    weight = np.asarray(total_weight_n, dtype=float)
    return mu * weight, (1.0 - mu) * weight
