"""Sm of (19): the contact-projected inverse inertia of the leg joints (Kim et al., Sec. III-C).

    (19)  ddtheta_j = S M^-1 (I - Pc) S^T tau_j =: Sm tau_j,   Pc = Jc^T Jc_bar^T,
          Jc_bar = M^-1 Jc^T (Jc M^-1 Jc^T)^-1   (dynamically consistent inverse of Jc),

so  M^-1 (I - Pc) = M^-1 - M^-1 Jc^T (Jc M^-1 Jc^T)^-1 Jc M^-1,  the inverse inertia of the
floating-base robot whose support foot cannot move. M is the (6 + 12) x (6 + 12) joint-space
inertia of the floating base and the legs (upper body locked), Jc the 6 x 18 Jacobian of the
support sole (both soles stacked, 12 x 18, in double support: the lab's code switches the foot
at mid double support instead; both are offered), S = [0 I] selects the legs.

pinocchio's `computeKKTContactDynamicMatrixInverse(model, data, q, Jc)` inverts the KKT matrix
[[M, Jc^T], [Jc, 0]]; its top-left block is exactly M^-1 - M^-1 Jc^T (Jc M^-1 Jc^T)^-1 Jc M^-1.
The projection depends only on the row space of Jc, so the frame the Jacobian is expressed in
does not matter (LOCAL here). Sm is symmetric positive semi-definite; the support leg's block is
small (the ground holds the foot), the swing leg's is that of a free leg.

Coupling: "full" keeps the 12 x 12 matrix; "diagonal" keeps only its diagonal, as the lab's code
did (12 decoupled joints, each with its own posture- and contact-dependent scalar).
"""

from __future__ import annotations

import enum

import numpy as np
import pinocchio as pin

from controller.humanoid.leg_model import N_LEG_JOINTS, LegModel
from controller.humanoid.support import LqrContact, SupportState


class SmCoupling(enum.Enum):
    FULL = "full"
    DIAGONAL = "diagonal"


class ContactProjectedInertia:
    """Computes Sm (12 x 12, lab leg order) for a posture and a support state.

    Sm does not depend on where the robot is or how it is turned in the world (the dynamics of
    the whole robot are invariant under rigid motions; the free flyer's velocity is expressed in
    the pelvis frame), so only the leg angles are needed.
    """

    def __init__(self, model: LegModel) -> None:
        self.leg_model = model
        self._data = model.model.createData()  # own data: may run in another thread than the GC

    def projected_inverse_inertia(
        self, link_angle_rad: np.ndarray, support: SupportState | LqrContact
    ) -> np.ndarray:
        """M^-1 (I - Pc), (6 + 12) x (6 + 12), in pinocchio's velocity order."""
        lm = self.leg_model
        model, data = lm.model, self._data
        q = lm.configuration(np.asarray(link_angle_rad, dtype=float))
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        contact = self.contact_jacobian(support)
        kkt_inverse = pin.computeKKTContactDynamicMatrixInverse(model, data, q, contact)
        return kkt_inverse[: model.nv, : model.nv]

    def contact_jacobian(self, support: SupportState | LqrContact) -> np.ndarray:
        """Jc: the support sole(s)' 6-D Jacobian(s), stacked (after computeJointJacobians)."""
        lm = self.leg_model
        return np.vstack(
            [
                pin.getFrameJacobian(
                    lm.model, self._data, lm.sole_frame_ids[side], pin.ReferenceFrame.LOCAL
                )
                for side in support.feet
            ]
        )

    def sm(
        self,
        link_angle_rad: np.ndarray,
        support: SupportState | LqrContact,
        coupling: SmCoupling = SmCoupling.FULL,
    ) -> np.ndarray:
        """Sm = S M^-1 (I - Pc) S^T for the 12 leg joints in the lab's order [1/(kg m^2)], the
        soles of `support` (a support state or the LQR's contact, controller.humanoid.support)
        held on the ground."""
        angles = np.asarray(link_angle_rad, dtype=float)
        if angles.shape != (N_LEG_JOINTS,):
            raise ValueError(f"link_angle_rad must have {N_LEG_JOINTS} entries, got {angles.shape}")
        projected = self.projected_inverse_inertia(angles, support)
        legs = self.leg_model.leg_v_index
        sm = projected[np.ix_(legs, legs)]
        sm = 0.5 * (sm + sm.T)  # symmetric up to round-off; make it exactly so
        if SmCoupling(coupling) is SmCoupling.DIAGONAL:
            return np.diag(np.diag(sm))
        return sm
