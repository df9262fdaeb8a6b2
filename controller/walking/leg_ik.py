"""Closed-form inverse kinematics of a 6-DoF leg: hip yaw-roll-pitch, knee, ankle pitch-roll.

Why closed form: DYROS-JET's leg has the structure that makes the analytic solution exact
(the three hip axes meet in one point, the two ankle axes meet in one point, and the knee and
ankle offsets lie in the pitch plane), so the solution is exact to rounding, has no iterations,
tolerance or solver dependency, and costs a fixed few tens of microseconds per leg in plain
Python. A numerical IK (pin-pink or damped least squares on pinocchio) would add a QP or an
iteration loop, a convergence tolerance and a warm-start state to a 200 Hz path, for a leg that
does not need it. The geometry is an argument (`LegGeometry`), built from figures or extracted
and checked from a pinocchio model (`LegGeometry.from_pinocchio`), so that the same function
serves any robot description of this structure and refuses one that is not.

Kinematics (every joint frame parallel to the pelvis at the zero pose, the structure checked):

    hip     p_h = p_pelvis + R_pelvis h
    thigh   R_t = R_pelvis Rz(q1) Rx(q2) Ry(q3),    knee  = p_h + R_t t0
    shank   R_s = R_t Ry(q4),                       ankle = knee + R_s s0
    foot    R_f = R_s Ry(q5) Rx(q6)

with q the rotations about the canonical axes (z, x, y, y, y, x); a joint whose axis is the
negative canonical axis (DYROS-JET: both hip yaws, the right leg's pitch joints) has joint
angle = -q. t0 = knee from hip and s0 = ankle from knee at the zero pose (y = 0).

Solution, with v = R_f' (ankle - p_h) (hip to ankle in the foot frame) and the angle
a(w) = atan2(w_z, w_x) of a vector in the x-z plane (Ry(q) turns a(w) into a(w) - q):

    knee     |t0 + Ry(q4) s0| = |v|:  cos(q4 + d) = (|v|^2 - |t0|^2 - |s0|^2) / (2 |t0| |s0|),
             d = a(t0) - a(s0);  q4 = acos(.) - d (the knee bent forward; q4 = -d is straight)
    ankle    w = Ry(-q4) t0 + s0 (hip to ankle in the shank frame), v = Rx(-q6) Ry(-q5) w:
             q6 = atan2(-v_y, -v_z),  q5 = a(u) - a(w) with u = (v_x, 0, -sqrt(v_y^2 + v_z^2))
    hip      Rz(q1) Rx(q2) Ry(q3) = R_pelvis' R_f Rx(-q6) Ry(-(q4 + q5)) = M:
             q2 = asin(M_21),  q1 = atan2(-M_01, M_11),  q3 = atan2(-M_20, M_22).

Branch: of the exact solutions, this is the one with the knee bent forward, |hip roll| and
|ankle roll| < 90 deg and the hip above the ankle in the ankle-pitch joint's frame: every walking
posture. For any reachable pose the returned angles reproduce the pose exactly (the tests check
both by forward kinematics on an independent pinocchio model).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from controller.walking import dyros_jet_figures as jet
from controller.walking.footsteps import Side

CANONICAL_AXES: tuple[tuple[float, float, float], ...] = (
    (0.0, 0.0, 1.0),  # hip yaw
    (1.0, 0.0, 0.0),  # hip roll
    (0.0, 1.0, 0.0),  # hip pitch
    (0.0, 1.0, 0.0),  # knee
    (0.0, 1.0, 0.0),  # ankle pitch
    (1.0, 0.0, 0.0),  # ankle roll
)


class LegIkError(ValueError):
    """The target is out of the leg's reach, or a geometry is not of the solvable structure."""


@dataclass(frozen=True)
class LegGeometry:
    """One leg: hip joint centre in the pelvis frame, knee from hip and ankle from knee at the
    zero pose [m] (y components zero), and each joint's axis sign against its canonical axis
    (z, x, y, y, y, x). The foot frame is the ankle-roll joint frame."""

    hip_in_pelvis_m: tuple[float, float, float]
    knee_from_hip_m: tuple[float, float, float]
    ankle_from_knee_m: tuple[float, float, float]
    axis_signs: tuple[int, int, int, int, int, int]
    thigh_length_m: float = field(init=False)
    shank_length_m: float = field(init=False)
    knee_offset_rad: float = field(init=False)

    def __post_init__(self) -> None:
        for name in ("hip_in_pelvis_m", "knee_from_hip_m", "ankle_from_knee_m"):
            value = tuple(float(v) for v in getattr(self, name))
            if len(value) != 3 or not all(math.isfinite(v) for v in value):
                raise LegIkError(f"{name} must be 3 finite numbers, got {getattr(self, name)!r}")
            object.__setattr__(self, name, value)
        for name in ("knee_from_hip_m", "ankle_from_knee_m"):
            if abs(getattr(self, name)[1]) > 1e-12:
                raise LegIkError(
                    f"{name} must lie in the pitch (x-z) plane (y = 0) for the closed form, "
                    f"got {getattr(self, name)}"
                )
        signs = tuple(int(s) for s in self.axis_signs)
        if len(signs) != 6 or any(s not in (-1, 1) for s in signs):
            raise LegIkError(f"axis_signs must be six values of +1 or -1, got {self.axis_signs!r}")
        object.__setattr__(self, "axis_signs", signs)
        tx, _, tz = self.knee_from_hip_m
        sx, _, sz = self.ankle_from_knee_m
        thigh, shank = math.hypot(tx, tz), math.hypot(sx, sz)
        if thigh <= 0 or shank <= 0:
            raise LegIkError("thigh and shank must have non-zero length")
        object.__setattr__(self, "thigh_length_m", thigh)
        object.__setattr__(self, "shank_length_m", shank)
        object.__setattr__(self, "knee_offset_rad", math.atan2(tz, tx) - math.atan2(sz, sx))

    @classmethod
    def dyros_jet(cls, side: Side) -> LegGeometry:
        """DYROS-JET's leg from its URDF figures (`dyros_jet_figures`)."""
        if side is Side.LEFT:
            return cls(
                jet.HIP_IN_PELVIS_LEFT_M,
                jet.KNEE_FROM_HIP_M,
                jet.ANKLE_FROM_KNEE_M,
                jet.AXIS_SIGNS_LEFT,
            )
        return cls(
            jet.HIP_IN_PELVIS_RIGHT_M,
            jet.KNEE_FROM_HIP_M,
            jet.ANKLE_FROM_KNEE_M,
            jet.AXIS_SIGNS_RIGHT,
        )

    @classmethod
    def from_pinocchio(cls, model, joint_names: Sequence[str], tolerance: float = 1e-9):
        """The geometry of a leg in a pinocchio model, from its six joints (hip yaw, hip roll,
        hip pitch, knee, ankle pitch, ankle roll; names as in the model), checked against the
        structure the closed form needs. The pelvis frame is the frame of the hip yaw joint's
        parent joint (the free-flyer of a floating-base model); the foot frame is the ankle
        roll joint's frame."""
        import pinocchio as pin

        if len(joint_names) != 6:
            raise LegIkError(f"need the leg's six joint names, got {list(joint_names)}")
        ids = []
        for name in joint_names:
            if not model.existJointName(name):
                raise LegIkError(f"joint {name!r} is not in the model")
            ids.append(model.getJointId(name))
        for index in range(1, 6):
            if model.parents[ids[index]] != ids[index - 1]:
                name = joint_names[index]
                raise LegIkError(f"joint {name!r} is not the child of the previous leg joint")
        placements = [model.jointPlacements[jid] for jid in ids]
        for name, placement in zip(joint_names, placements, strict=True):
            if not np.allclose(placement.rotation, np.eye(3), atol=tolerance):
                raise LegIkError(
                    f"joint {name!r}: its placement is rotated; the closed form "
                    "needs joint frames parallel to the pelvis at the zero pose"
                )
        for index in (1, 2, 5):
            if np.linalg.norm(placements[index].translation) > tolerance:
                raise LegIkError(
                    f"joint {joint_names[index]!r} is offset from the previous "
                    "joint; the closed form needs intersecting hip and ankle axes"
                )
        data = model.createData()
        q = pin.neutral(model)
        pin.computeJointJacobians(model, data, q)
        signs = []
        for name, jid, canonical in zip(joint_names, ids, CANONICAL_AXES, strict=True):
            if model.joints[jid].nv != 1:
                raise LegIkError(f"joint {name!r} is not a one-DoF joint")
            column = pin.getJointJacobian(model, data, jid, pin.ReferenceFrame.LOCAL)[
                :, model.joints[jid].idx_v
            ]
            linear, angular = column[:3], column[3:]
            sign = float(np.dot(angular, canonical))
            if (
                np.linalg.norm(linear) > tolerance
                or abs(abs(sign) - 1.0) > tolerance
                or np.linalg.norm(angular - sign * np.array(canonical)) > tolerance
            ):
                raise LegIkError(f"joint {name!r} is not a revolute joint about +-{canonical}")
            signs.append(1 if sign > 0 else -1)
        return cls(
            tuple(placements[0].translation),
            tuple(placements[3].translation),
            tuple(placements[4].translation),
            tuple(signs),
        )


@dataclass(frozen=True)
class LegsGeometry:
    """Both legs; joint order of the 12-vector: left (hip yaw, roll, pitch, knee, ankle pitch,
    roll), then right, as the lab's controller orders them."""

    left: LegGeometry
    right: LegGeometry

    @classmethod
    def dyros_jet(cls) -> LegsGeometry:
        return cls(LegGeometry.dyros_jet(Side.LEFT), LegGeometry.dyros_jet(Side.RIGHT))

    def leg(self, side: Side) -> LegGeometry:
        return self.left if side is Side.LEFT else self.right


def leg_inverse_kinematics(
    geometry: LegGeometry,
    pelvis_position_m: np.ndarray,
    pelvis_rotation: np.ndarray,
    foot_position_m: np.ndarray,
    foot_rotation: np.ndarray,
) -> tuple[float, float, float, float, float, float]:
    """The six joint angles [rad] (hip yaw, roll, pitch, knee, ankle pitch, roll) that put the
    foot frame (ankle-roll joint frame) at the given pose, the pelvis at its pose (world frame;
    rotations as 3x3 matrices). Raises LegIkError when the ankle is out of the leg's reach."""
    px, py, pz = (float(v) for v in pelvis_position_m)
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = (
        (float(a), float(b), float(c)) for a, b, c in pelvis_rotation
    )
    (f00, f01, f02), (f10, f11, f12), (f20, f21, f22) = (
        (float(a), float(b), float(c)) for a, b, c in foot_rotation
    )
    ax, ay, az = (float(v) for v in foot_position_m)
    hx, hy, hz = geometry.hip_in_pelvis_m
    # Hip to ankle, world, then in the foot frame.
    dx = ax - (px + r00 * hx + r01 * hy + r02 * hz)
    dy = ay - (py + r10 * hx + r11 * hy + r12 * hz)
    dz = az - (pz + r20 * hx + r21 * hy + r22 * hz)
    vx = f00 * dx + f10 * dy + f20 * dz
    vy = f01 * dx + f11 * dy + f21 * dz
    vz = f02 * dx + f12 * dy + f22 * dz
    # Knee from the hip-ankle distance.
    a, b = geometry.thigh_length_m, geometry.shank_length_m
    distance_sq = vx * vx + vy * vy + vz * vz
    cos_bend = (distance_sq - a * a - b * b) / (2.0 * a * b)
    if cos_bend > 1.0 + 1e-12 or cos_bend < -1.0 - 1e-12:
        raise LegIkError(
            f"ankle out of reach: hip-ankle distance {math.sqrt(distance_sq):.4f} m, the leg "
            f"reaches {abs(a - b):.4f}..{a + b:.4f} m"
        )
    q4 = math.acos(min(1.0, max(-1.0, cos_bend))) - geometry.knee_offset_rad
    # Hip to ankle in the shank frame: w = Ry(-q4) t0 + s0.
    tx, _, tz = geometry.knee_from_hip_m
    sx, _, sz = geometry.ankle_from_knee_m
    c4, s4 = math.cos(q4), math.sin(q4)
    wx = tx * c4 - tz * s4 + sx
    wz = tx * s4 + tz * c4 + sz
    # Ankle roll and pitch.
    q6 = math.atan2(-vy, -vz)
    uz = -math.sqrt(vy * vy + vz * vz)
    q5 = math.atan2(uz, vx) - math.atan2(wz, wx)
    q5 = (q5 + math.pi) % (2.0 * math.pi) - math.pi
    # Hip: M = R_pelvis' R_foot Rx(-q6) Ry(-(q4 + q5)); only rows/entries needed are formed.
    # G = R_pelvis' R_foot.
    g = [
        [
            r00 * f00 + r10 * f10 + r20 * f20,
            r00 * f01 + r10 * f11 + r20 * f21,
            r00 * f02 + r10 * f12 + r20 * f22,
        ],
        [
            r01 * f00 + r11 * f10 + r21 * f20,
            r01 * f01 + r11 * f11 + r21 * f21,
            r01 * f02 + r11 * f12 + r21 * f22,
        ],
        [
            r02 * f00 + r12 * f10 + r22 * f20,
            r02 * f01 + r12 * f11 + r22 * f21,
            r02 * f02 + r12 * f12 + r22 * f22,
        ],
    ]
    c6, s6 = math.cos(q6), math.sin(q6)
    beta = q4 + q5
    cb, sb = math.cos(beta), math.sin(beta)
    # N = Rx(-q6) Ry(-beta) = [[cb, 0, -sb], [s6 sb, c6, s6 cb], [c6 sb, -s6, c6 cb]].
    n = ((cb, 0.0, -sb), (s6 * sb, c6, s6 * cb), (c6 * sb, -s6, c6 * cb))

    def m(i: int, j: int) -> float:
        return g[i][0] * n[0][j] + g[i][1] * n[1][j] + g[i][2] * n[2][j]

    q2 = math.asin(min(1.0, max(-1.0, m(2, 1))))
    q1 = math.atan2(-m(0, 1), m(1, 1))
    q3 = math.atan2(-m(2, 0), m(2, 2))
    s = geometry.axis_signs
    return (s[0] * q1, s[1] * q2, s[2] * q3, s[3] * q4, s[4] * q5, s[5] * q6)


def legs_inverse_kinematics(
    legs: LegsGeometry,
    pelvis_position_m: np.ndarray,
    pelvis_rotation: np.ndarray,
    left_foot_position_m: np.ndarray,
    left_foot_rotation: np.ndarray,
    right_foot_position_m: np.ndarray,
    right_foot_rotation: np.ndarray,
) -> np.ndarray:
    """The 12 leg joint angles [rad], left leg then right (see `LegsGeometry`)."""
    left = leg_inverse_kinematics(
        legs.left, pelvis_position_m, pelvis_rotation, left_foot_position_m, left_foot_rotation
    )
    right = leg_inverse_kinematics(
        legs.right, pelvis_position_m, pelvis_rotation, right_foot_position_m, right_foot_rotation
    )
    return np.array(left + right)
