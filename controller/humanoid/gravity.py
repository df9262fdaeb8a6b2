"""The humanoid gravity compensator, Kim et al., ICRA 2018, Sec. III-A, (5)-(8), for the legs.

(5)  tau_g = Jr^T fr + Jl^T fl,  J = the Jacobian "from the CoM to the contact point":
         J_i = d(p_i - p_com)/d theta  (leg columns of the floating-base Jacobians),
(6)  fr = mu f,  fl = (1 - mu) f,  f = m g = (0, 0, -m * 9.81)  the robot's WEIGHT vector,
(7)  mu = the CoM's position between the feet (`controller.gravity.support_force_split`):
         0 in left single support, 1 in right single support,
(8)  ug = K^-1 tau_g  (`controller.gravity.GravityCompensator`).

Sign convention (settled against the MuJoCo plant's static spring torques): tau_g is the torque
the gear spring must carry, tau_j = K (theta_m - theta_j) of (1), in each joint's own axis
convention; f is the weight, pointing DOWN. With f pointing up (the support force the ground
gives) or with J = d(p_com - p_i)/d theta the sign of every entry flips: that is the +33 N m
where the plant's knee spring carries about -31 N m. Why this sign is right: summing (5) with
fr + fl = f gives tau_g = (Jr^T fr + Jl^T fl)_legs - J_com^T f, where -J_com^T f = m g dz_com/d theta
is the generalised gravity g(theta) of (3) and (Ji^T fi) removes what the ground carries: it is
the static balance S^T tau_j = g(theta) + Jc^T fc of (3) with the contact forces fc = -fi.

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

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from controller.gravity import STANDARD_GRAVITY_M_S2, GravityModel, support_force_split
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
        self.base_rotation: np.ndarray | None = None
        self.last_split: SupportForces | None = None

    def set_support(self, support: SupportState) -> None:
        self.support = SupportState(support)

    def set_base_rotation(self, rotation: np.ndarray | None) -> None:
        """A measured pelvis orientation (world <- pelvis), or None: from the flat support sole."""
        self.base_rotation = None if rotation is None else np.array(rotation, dtype=float)

    def pelvis_rotation(self, link_angle_rad: np.ndarray) -> np.ndarray:
        """The pelvis orientation tau_g is evaluated at (see the module docstring)."""
        if self.base_rotation is not None:
            return self.base_rotation
        lm = self.leg_model
        feet = self.support.feet
        if len(feet) == 1:
            return lm.base_rotation_for_flat_sole(link_angle_rad, feet[0])
        left = lm.base_rotation_for_flat_sole(link_angle_rad, 0)
        right = lm.base_rotation_for_flat_sole(link_angle_rad, 1)
        return left @ pin.exp3(0.5 * pin.log3(left.T @ right))

    def gravity_torque(self, link_angle_rad: np.ndarray) -> np.ndarray:
        angles = np.asarray(link_angle_rad, dtype=float)
        if angles.shape != (N_LEG_JOINTS,):
            raise ValueError(f"link_angle_rad must have {N_LEG_JOINTS} entries, got {angles.shape}")
        lm = self.leg_model
        model, data = lm.model, lm.data
        q = lm.configuration(angles, base_rotation=self.pelvis_rotation(angles))
        lm.update_jacobians(q)
        com = data.com[0].copy()
        jacobian_com = data.Jcom
        split = self.split(com)
        forces = (split.left_force_n, split.right_force_n)
        points = (split.left_point_m, split.right_point_m)
        torque = np.zeros(model.nv)
        for side in (0, 1):
            if not np.any(forces[side]):
                # (J_i - J_com)^T 0 = 0; the J_com part of the other foot's term still counts
                continue
            torque += (self._point_jacobian(side, points[side]) - jacobian_com).T @ forces[side]
        self.last_split = split
        return torque[lm.leg_v_index]

    def split(self, com_m: np.ndarray) -> SupportForces:
        """(6)-(7) with the contact points of the module docstring (after update_kinematics)."""
        lm = self.leg_model
        left = lm.sole_placement(0).translation.copy()
        right = lm.sole_placement(1).translation.copy()
        if self.support is SupportState.LEFT:
            mu = 0.0
        elif self.support is SupportState.RIGHT:
            mu = 1.0
        else:
            right_force, _ = support_force_split(com_m, left, right, 1.0)
            mu = float(right_force)
        on_line = left + mu * (right - left)
        offset = com_m - on_line
        offset[2] = 0.0
        return SupportForces(
            mu=mu,
            left_force_n=(1.0 - mu) * self.weight_n,
            right_force_n=mu * self.weight_n,
            left_point_m=left + offset,
            right_point_m=right + offset,
            com_m=com_m,
        )

    def _point_jacobian(self, side: int, point_m: np.ndarray) -> np.ndarray:
        """3 x nv Jacobian of the foot-fixed point now at `point_m` (world), world axes."""
        lm = self.leg_model
        frame_id = lm.sole_frame_ids[side]
        jacobian = pin.getFrameJacobian(
            lm.model, lm.data, frame_id, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        )
        lever = point_m - lm.data.oMf[frame_id].translation
        # v_point = v_frame + omega x lever = v_frame - lever x omega
        return jacobian[:3] - pin.skew(lever) @ jacobian[3:]
