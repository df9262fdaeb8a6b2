"""The controller's rigid-body model of a fixed-base robot of flexible joints (pinocchio), from
URDF text: Kim et al., ICRA 2018, with the base bolted down.

- The URDF is built as it is (its root fixed to the world, no free flyer); every movable joint
  that is not one of the robot's flexible joints is locked at a stated angle (0 by default) with
  `pinocchio.buildReducedModel`, leaving exactly the configured joints, in the configured order.
- (5)-(8) with a fixed base: the gravity torque is the generalised gravity of the joints,
  tau_g(theta) = g(theta) (`computeGeneralizedGravity`): the torque each gear spring must carry
  to hold the links still, K (theta_m - theta_j) = g(theta_j) of (1) at rest (the humanoid's
  support split (6)-(7) has nothing to split: the base carries what the joints do not). The
  joints are coupled: joint i carries every link beyond it, at the angles of all of them.
- Sm of (19) with no contact: S M^-1 S^T = M(theta)^-1 (every joint of the reduced model is
  actuated, S = I), posture-dependent and full (`FixedBaseInertia`; its diagonal for the lab's
  per-joint design).

Conventions: angles rad, gravity -9.81 m/s^2 along the URDF world's z (pinocchio's default),
every joint angle in its URDF axis convention, joint order the caller's.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pinocchio as pin

from controller.gravity import GravityModel

MOVABLE_JOINT_TYPES = ("revolute", "continuous")


class FixedBaseModel:
    """pinocchio model of the robot's flexible joints, every other movable joint locked.

    Attributes: `model`, `data` (one `data` per FixedBaseModel: not thread-safe), `full_model`,
    `joint_names` (the caller's order), `q_index`/`v_index` (pinocchio's place of each).
    """

    def __init__(
        self,
        urdf_text: str,
        joint_names: Sequence[str],
        locked_angles_rad: Mapping[str, float] | None = None,
    ) -> None:
        locked = dict(locked_angles_rad or {})
        full = pin.buildModelFromXML(urdf_text)
        names = tuple(joint_names)
        known = {full.names[i] for i in range(1, full.njoints)}
        missing = [name for name in names if name not in known]
        if missing:
            raise ValueError(f"the robot description has no joints {missing}")
        unknown = sorted(set(locked) - known)
        if unknown:
            raise ValueError(f"locked angles name joints the description lacks: {unknown}")
        overlap = sorted(set(locked) & set(names))
        if overlap:
            raise ValueError(f"joints both flexible and locked: {overlap}")
        q_lock = pin.neutral(full)
        lock_ids = []
        for joint_id in range(1, full.njoints):
            name = full.names[joint_id]
            if name in names:
                continue
            joint = full.joints[joint_id]
            if joint.nq != 1:
                raise ValueError(f"joint {name!r}: only one-axis joints can be locked")
            q_lock[joint.idx_q] = float(locked.get(name, 0.0))
            lock_ids.append(joint_id)
        model = pin.buildReducedModel(full, lock_ids, q_lock) if lock_ids else full
        for name in names:
            if model.joints[model.getJointId(name)].nv != 1:
                raise ValueError(f"joint {name!r} is not a one-axis joint")
        self.full_model = full
        self.model = model
        self.data = model.createData()
        self.joint_names = names
        self.locked_angles_rad = {
            full.names[i]: float(q_lock[full.joints[i].idx_q]) for i in lock_ids
        }
        self.q_index = np.array([model.joints[model.getJointId(n)].idx_q for n in names])
        self.v_index = np.array([model.joints[model.getJointId(n)].idx_v for n in names])
        self.total_mass_kg = float(pin.computeTotalMass(model))

    @property
    def n_joints(self) -> int:
        return len(self.joint_names)

    def configuration(self, link_angle_rad: Sequence[float] | np.ndarray) -> np.ndarray:
        """pinocchio's q for these link angles (the caller's joint order)."""
        angles = np.asarray(link_angle_rad, dtype=float)
        if angles.shape != (self.n_joints,):
            raise ValueError(
                f"link_angle_rad must have {self.n_joints} entries, got {angles.shape}"
            )
        q = pin.neutral(self.model)
        q[self.q_index] = angles
        return q

    def gravity_torque(self, link_angle_rad: Sequence[float] | np.ndarray) -> np.ndarray:
        """tau_g = g(theta) [N m], the caller's joint order (module docstring)."""
        q = self.configuration(link_angle_rad)
        return pin.computeGeneralizedGravity(self.model, self.data, q)[self.v_index].copy()

    def mass_matrix(
        self, link_angle_rad: Sequence[float] | np.ndarray, data: pin.Data | None = None
    ) -> np.ndarray:
        """M(theta), n x n, the caller's joint order (`data`: another thread's own)."""
        q = self.configuration(link_angle_rad)
        mass = pin.crba(self.model, self.data if data is None else data, q)
        mass = np.triu(mass) + np.triu(mass, 1).T  # crba fills the upper triangle
        return mass[np.ix_(self.v_index, self.v_index)]

    def frame_position_m(
        self, frame: str, link_angle_rad: Sequence[float] | np.ndarray
    ) -> np.ndarray:
        """A frame's (a link's) origin in the world [m] at these link angles."""
        if not self.model.existFrame(frame):
            raise ValueError(f"the robot description has no frame {frame!r}")
        q = self.configuration(link_angle_rad)
        pin.forwardKinematics(self.model, self.data, q)
        pin.updateFramePlacements(self.model, self.data)
        return self.data.oMf[self.model.getFrameId(frame)].translation.copy()


class FixedBaseGravity(GravityModel):
    """tau_g of (5)-(8) with a fixed base (`FixedBaseModel.gravity_torque`)."""

    def __init__(self, model: FixedBaseModel) -> None:
        self.model = model

    def gravity_torque(self, link_angle_rad: np.ndarray) -> np.ndarray:
        return self.model.gravity_torque(link_angle_rad)


class FixedBaseInertia:
    """Sm of (19) with no contact: S M^-1 S^T = M(theta)^-1, full or its diagonal."""

    def __init__(self, model: FixedBaseModel) -> None:
        self.model = model
        self._data = model.model.createData()  # own data: may run in another thread than the GC

    def sm(self, link_angle_rad: np.ndarray, diagonal: bool = False) -> np.ndarray:
        sm = np.linalg.inv(self.model.mass_matrix(link_angle_rad, self._data))
        sm = 0.5 * (sm + sm.T)  # symmetric up to round-off; make it exactly so
        return np.diag(np.diag(sm)) if diagonal else sm
