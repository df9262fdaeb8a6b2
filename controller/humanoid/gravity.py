"""The humanoid gravity compensator, Kim et al., ICRA 2018, Sec. III-A, (5)-(8), for the legs.

(5)  tau_g = Jr^T fr + Jl^T fl,  J = the Jacobian "from the CoM to the contact point":
         J_i = d(p_i - p_com)/d theta  (leg columns of the floating-base Jacobians),
(6)  fr = mu f,  fl = (1 - mu) f,  f = m g = (0, 0, -m * 9.81)  the robot's WEIGHT vector,
(7)  mu = the CoM's position between the feet (`controller.gravity.support_force_split`):
         0 in left single support, 1 in right single support,
(8)  ug = C tau_g, C the paper's K^-1 or the whole joint's compliance
     (`controller.gravity.GravityCompensator`, `GcCompliance`).

For a planned motion (ours, beyond the paper's static (5): `set_planned_load`, fed from a
walk's pattern, controller/planned_motion.py): f = m (g - a) with a the planned CoM
acceleration (d'Alembert, the whole mass accelerating with the CoM: the line of f through the
CoM meets the ground at the cart-table's ZMP c - (z_c / g) a), and in double support mu where
the plan's ZMP lies between the feet instead of the CoM. On a compliant leg this is what the
joints must carry along the plan: in a 0.8 s / 0.3 s walk the CoM accelerates sideways at up
to ~1 m/s^2, ~40 N m at the stance ankle roll, 70 mrad of deflection through C that the static
(5) leaves (docs/walking.md). The vectors are in the frame of the flat support sole (a straight
walk's world).

Sign convention (settled against the MuJoCo plant's static spring torques): tau_g is the torque
the gear spring must carry, tau_j = K (theta_m - theta_j) of (1), in each joint's own axis
convention; f is the weight, pointing DOWN. With f pointing up (the support force the ground
gives) or with J = d(p_com - p_i)/d theta the sign of every entry flips: that is the +33 N m
where the plant's knee spring carries about -31 N m. Why this sign is right: with fr + fl = f,
(5) reads tau_g = (Jr^T fr + Jl^T fl)_legs - (J_com^T f)_legs, where -J_com^T f = m g dz_com/dtheta
is the generalised gravity g(theta) of (3); so S^T tau_g = g(theta) + Jc^T fc, the static
balance of (3) with fc = (fr, fl), the forces the feet press onto the ground.

Contact points: (5) with point forces is the exact static balance only if the forces' centre of
pressure lies under the CoM. We therefore apply each foot's force at its sole centre shifted
horizontally by the CoM's offset from the line between the sole centres (in single support:
the point of the sole under the CoM). Then sum(fi) = f and the moments about the CoM vanish, so
tau_g is the exact holding torque of the rigid robot for this split (also when the CoM is not
on the line between the feet). In double support the split is the paper's modelling choice
(the robot is statically indeterminate there): no internal force between the feet.

Where the pelvis orientation comes from: tau_g depends on the direction of gravity in the robot.
The compensator is a feed-forward evaluated at the desired link angles (as in the lab's code),
so by default the pelvis is oriented such that the support sole is flat on level ground (double
support: halfway between the two soles' orientations, which coincide for a consistent posture).
`base_rotation` can be set to a measured pelvis orientation instead (an IMU).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from controller.gravity import STANDARD_GRAVITY_M_S2, GravityModel
from controller.humanoid.leg_model import N_LEG_JOINTS, LegModel
from controller.humanoid.support import SupportState


@dataclass(frozen=True)
class SupportForces:
    """The split (6)-(7) at one posture: weight vectors [N] per foot and where they act [m]."""

    mu: float
    left_force_n: np.ndarray
    right_force_n: np.ndarray
    left_point_m: np.ndarray
    right_point_m: np.ndarray
    com_m: np.ndarray


class HumanoidLegGravity(GravityModel):
    """tau_g of (5)-(7) for the 12 leg joints (lab order), a `controller.gravity.GravityModel`.

    model: the controller's LegModel (nominal figures).
    support: the support state (`set_support` changes it between ticks).
    total_mass_kg: m in f = m g; default the model's total mass (the lab's code used 46.892 kg).
    """

    def __init__(
        self,
        model: LegModel,
        support: SupportState = SupportState.DOUBLE,
        *,
        total_mass_kg: float | None = None,
        gravity_m_s2: float = STANDARD_GRAVITY_M_S2,
    ) -> None:
        self.leg_model = model
        self.support = SupportState(support)
        mass = model.total_mass_kg if total_mass_kg is None else float(total_mass_kg)
        if not (np.isfinite(mass) and mass > 0):
            raise ValueError(f"total_mass_kg must be finite and > 0, got {total_mass_kg}")
        self.total_mass_kg = mass
        self.weight_n = np.array([0.0, 0.0, -mass * gravity_m_s2])
        self._static_weight_n = self.weight_n.copy()
        self._planned_split: float | None = None
        self._load_key: tuple | None = None
        self._base_rotation: np.ndarray | None = None
        self._base_key: bytes | None = None
        self._split: tuple | None = None
        self._cache_key: tuple | None = None
        self._q = model.configuration(np.zeros(N_LEG_JOINTS))  # pelvis at the identity
        self._wrench = np.zeros(6)
        legs = model.leg_v_index
        contiguous = np.array_equal(legs, np.arange(legs[0], legs[0] + N_LEG_JOINTS))
        self._legs = slice(int(legs[0]), int(legs[0]) + N_LEG_JOINTS) if contiguous else legs
        self._cache_torque = np.zeros(N_LEG_JOINTS)

    def set_support(self, support: SupportState) -> None:
        self.support = SupportState(support)

    def set_planned_load(
        self, com_acceleration_mps2: np.ndarray | None, support_split: float | None
    ) -> None:
        """(5)-(7) for a planned motion (module docstring): f = m (g - a) with the planned CoM
        acceleration a, and mu = support_split in double support; None, None: the static
        weight and mu from the CoM (the paper's)."""
        if com_acceleration_mps2 is None:
            self.weight_n = self._static_weight_n.copy()
        else:
            acceleration = np.asarray(com_acceleration_mps2, dtype=float)
            self.weight_n = self._static_weight_n - self.total_mass_kg * acceleration
        if support_split is not None and not 0.0 <= support_split <= 1.0:
            raise ValueError(f"support_split must be in [0, 1], got {support_split}")
        self._planned_split = support_split
        loaded = com_acceleration_mps2 is not None or support_split is not None
        self._load_key = (self.weight_n.tobytes(), support_split) if loaded else None

    @property
    def base_rotation(self) -> np.ndarray | None:
        """The measured pelvis orientation in use, or None (from the flat support sole)."""
        return None if self._base_rotation is None else self._base_rotation.copy()

    def set_base_rotation(self, rotation: np.ndarray | None) -> None:
        """A measured pelvis orientation (world <- pelvis), or None: from the flat support sole."""
        if rotation is None:
            self._base_rotation = self._base_key = None
            return
        self._base_rotation = np.array(rotation, dtype=float).reshape(3, 3)
        self._base_key = self._base_rotation.tobytes()

    def pelvis_rotation(self, link_angle_rad: np.ndarray) -> np.ndarray:
        """The pelvis orientation tau_g is evaluated at (see the module docstring)."""
        lm = self.leg_model
        lm.update_kinematics(lm.configuration(np.asarray(link_angle_rad, dtype=float)))
        return self._pelvis_rotation_from_kinematics()

    def _pelvis_rotation_from_kinematics(self) -> np.ndarray:
        """world <- pelvis, from the sole placements computed with the pelvis at the identity."""
        if self._base_rotation is not None:
            return self._base_rotation
        lm = self.leg_model
        soles = [lm.data.oMf[frame] for frame in lm.sole_frame_ids]  # pelvis <- sole
        return self._pelvis_rotation(soles[0].rotation, soles[1].rotation)

    def _pelvis_rotation(self, left_sole: np.ndarray, right_sole: np.ndarray) -> np.ndarray:
        """world <- pelvis from the soles' orientations (pelvis <- sole), the pelvis at the
        identity: the support sole flat, or halfway between the two in double support."""
        if self._base_rotation is not None:
            return self._base_rotation
        support = self.support
        if support is SupportState.DOUBLE:
            sole = left_sole @ _half_rotation(left_sole.T @ right_sole)
        else:
            sole = left_sole if support is SupportState.LEFT else right_sole
        return sole.T  # the sole flat: world <- sole = identity

    def gravity_torque(self, link_angle_rad: np.ndarray) -> np.ndarray:
        """tau_g (5) at these link angles [N m], lab leg order.

        Evaluated with the pelvis at the identity and the weight w expressed in pelvis
        coordinates (one kinematics pass; the torques do not depend on where the robot is):
        J_world = R J_pelvis, so J_world^T f = J_pelvis^T (R^T f). Since fr + fl = f = w,
        (5) = sum_i J_i^T f_i - J_com^T w. Both contact points are their sole centres o_i
        shifted by the same horizontal offset d (module docstring), so the force f_i = s_i w
        (s = 1 - mu, mu) at o_i + d is the wrench s_i [w; d x w] at the sole frame, and
        sum_i J_i^T f_i = (s_l J6_l + s_r J6_r)^T [w; d x w] with the soles' 6-D Jacobians.
        """
        angles = np.asarray(link_angle_rad, dtype=float)
        if angles.shape != (N_LEG_JOINTS,):
            raise ValueError(f"link_angle_rad must have {N_LEG_JOINTS} entries, got {angles.shape}")
        key = (angles.tobytes(), self.support, self._base_key, self._load_key)
        if key == self._cache_key:  # a held reference (standing): no kinematics again
            return self._cache_torque.copy()
        lm = self.leg_model
        model, data = lm.model, lm.data
        q = self._q
        q[lm.leg_q_index] = angles
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        pin.jacobianCenterOfMass(model, data, True)
        left_sole, right_sole = (data.oMf[frame] for frame in lm.sole_frame_ids)
        rotation = self._pelvis_rotation(left_sole.rotation, right_sole.rotation)
        weight = rotation.T @ self.weight_n
        com = data.com[0]
        left, right = left_sole.translation, right_sole.translation
        if self.support is SupportState.LEFT:
            mu = 0.0
        elif self.support is SupportState.RIGHT:
            mu = 1.0
        elif self._planned_split is not None:
            mu = self._planned_split
        else:
            # (7) as controller.gravity.support_force_split computes it, inline (hot path)
            across = right - left
            mu = min(1.0, max(0.0, float((com - left) @ across / (across @ across))))
        offset = com - (left + mu * (right - left))
        offset -= (offset @ weight) / (weight @ weight) * weight  # horizontal: _|_ to w
        wrench = self._wrench
        wrench[:3] = weight
        wrench[3:] = _cross(offset, weight)
        legs = self._legs
        jacobians = 0.0
        for side, share in ((0, 1.0 - mu), (1, mu)):
            if share != 0.0:
                jacobian = pin.getFrameJacobian(
                    model, data, lm.sole_frame_ids[side], pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
                )
                jacobians = jacobians + share * jacobian[:, legs]
        torque = jacobians.T @ wrench - data.Jcom[:, legs].T @ weight
        self._split = (mu, left.copy(), right.copy(), offset, com.copy(), rotation.copy())
        self._cache_key, self._cache_torque = key, torque.copy()
        return torque

    @property
    def last_split(self) -> SupportForces | None:
        """The split (6)-(7) of the last gravity_torque call, world frame (None before one)."""
        if self._split is None:
            return None
        mu, left, right, offset, com, rotation = self._split
        return SupportForces(
            mu=mu,
            left_force_n=(1.0 - mu) * self.weight_n,
            right_force_n=mu * self.weight_n,
            left_point_m=rotation @ (left + offset),
            right_point_m=rotation @ (right + offset),
            com_m=rotation @ com,
        )


def _half_rotation(rotation: np.ndarray) -> np.ndarray:
    """exp(log(R) / 2): the rotation about the same axis by half the angle (Rodrigues; the
    same as pinocchio's exp3(0.5 * log3(R)) for angles below pi, several times faster)."""
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = rotation.tolist()
    vee = np.array([r21 - r12, r02 - r20, r10 - r01])
    sin_angle = 0.5 * math.sqrt(float(vee @ vee))
    cos_angle = 0.5 * (r00 + r11 + r22 - 1.0)
    angle = math.atan2(sin_angle, cos_angle)
    if angle < 1e-12:
        return np.eye(3)
    x, y, z = (vee / (2.0 * sin_angle)).tolist()
    k = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    half = 0.5 * angle
    return np.eye(3) + math.sin(half) * k + (1.0 - math.cos(half)) * (k @ k)


def _cross(a: np.ndarray, b: np.ndarray) -> list[float]:
    """a x b for 3-vectors, in Python numbers (np.cross is slow on tiny arrays; the same
    products and differences)."""
    (a0, a1, a2), (b0, b1, b2) = a.tolist(), b.tolist()
    return [a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0]
