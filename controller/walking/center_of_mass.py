"""The whole robot's centre of mass for a pelvis pose and the 12 leg angles.

Why the pattern needs it: the cart-table plans the CoM, but the IK places the pelvis. A real
robot's CoM is not at its pelvis origin (DYROS-JET's URDF puts it about 5 cm ahead of the pelvis
at the zero pose) and moves with the swing leg, so "pelvis = CoM" would shift the measured ZMP
by centimetres that are the generator's, not the plant's. With a `CenterOfMassModel`,
`WalkingPattern` solves, tick by tick, for the pelvis position whose IK posture puts the model's
CoM on the planned CoM.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import numpy as np


class CenterOfMassModel(Protocol):
    def __call__(
        self,
        pelvis_position_m: np.ndarray,
        pelvis_rotation: np.ndarray,
        joint_angles_rad: np.ndarray,
    ) -> np.ndarray:
        """The CoM (3,) [m] in the world frame; joint_angles_rad (12,) as in `LegsGeometry`."""
        ...


class PinocchioCenterOfMass:
    """CoM of a pinocchio model with a free-flyer root joint (the pelvis) and the 12 leg joints
    named in `leg_joint_names` (left hip yaw..ankle roll, then right). Every other joint stays at
    `reference_configuration` (default: the model's neutral configuration)."""

    def __init__(
        self,
        model,
        leg_joint_names: Sequence[str],
        reference_configuration: np.ndarray | None = None,
    ) -> None:
        import pinocchio as pin

        self._pin = pin
        if model.njoints < 2 or model.joints[1].nq != 7 or model.joints[1].nv != 6:
            raise ValueError("the model's first joint must be a free-flyer carrying the pelvis")
        if len(leg_joint_names) != 12:
            raise ValueError(f"need 12 leg joint names, got {len(leg_joint_names)}")
        indices = []
        for name in leg_joint_names:
            if not model.existJointName(name):
                raise ValueError(f"joint {name!r} is not in the model")
            joint = model.joints[model.getJointId(name)]
            if joint.nq != 1:
                raise ValueError(f"joint {name!r} is not a one-DoF joint")
            indices.append(joint.idx_q)
        self.model = model
        self.data = model.createData()
        q = pin.neutral(model) if reference_configuration is None else reference_configuration
        self._q = np.array(q, dtype=float)
        self._leg_indices = np.array(indices)

    def __call__(
        self,
        pelvis_position_m: np.ndarray,
        pelvis_rotation: np.ndarray,
        joint_angles_rad: np.ndarray,
    ) -> np.ndarray:
        q = self._q
        q[:3] = pelvis_position_m
        q[3:7] = self._pin.Quaternion(np.asarray(pelvis_rotation)).coeffs()
        q[self._leg_indices] = joint_angles_rad
        return np.array(self._pin.centerOfMass(self.model, self.data, q))
