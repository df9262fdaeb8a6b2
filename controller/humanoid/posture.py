"""Standing postures of DYROS-JET's legs: where the feet are, where the CoM is, pelvis upright.

A posture is solved by whole-body inverse kinematics on the floating-base LegModel (damped
Gauss-Newton on pinocchio's Lie group): 18 unknowns (pelvis pose, 12 leg angles), 18 equations:

    left sole pose  = its target (6)        right sole pose = its target (6)
    CoM x, y        = its target (2)        pelvis roll, pitch, yaw = 0 (3)
    pelvis height   = its target (1)

Sole targets are the centre of the sole's bottom face with the sole flat (world axes); a sole on
the ground has z = 0. Used offline (experiment set-up, tests), not on the 200 Hz path.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from controller.humanoid.leg_model import N_LEG_JOINTS, LegModel

_BASE_FRAME = "base_link"


@dataclass(frozen=True)
class PostureTarget:
    """Where the soles (centre of the bottom face, flat) and the CoM should be [m]."""

    left_sole_m: tuple[float, float, float]
    right_sole_m: tuple[float, float, float]
    com_xy_m: tuple[float, float]
    pelvis_height_m: float


@dataclass(frozen=True)
class SolvedPosture:
    """IK result: leg angles (lab order) [rad], pinocchio q, and the largest residual."""

    leg_angles_rad: np.ndarray
    configuration: np.ndarray
    residual: float
    iterations: int


class PostureError(RuntimeError):
    """The IK did not converge (target out of reach)."""


def solve_posture(
    model: LegModel,
    target: PostureTarget,
    initial_leg_angles_rad: np.ndarray,
    *,
    tolerance: float = 1e-10,
    max_iterations: int = 100,
    damping: float = 1e-9,
) -> SolvedPosture:
    """Solve the 18 x 18 system of the module docstring from an initial guess."""
    pm, data = model.model, model.data
    base_frame = pm.getFrameId(_BASE_FRAME)
    q = model.configuration(initial_leg_angles_rad)
    q[2] = target.pelvis_height_m
    sole_targets = [
        pin.SE3(np.eye(3), np.asarray(target.left_sole_m, dtype=float)),
        pin.SE3(np.eye(3), np.asarray(target.right_sole_m, dtype=float)),
    ]
    residual = np.inf
    for iteration in range(1, max_iterations + 1):
        model.update_jacobians(q)
        errors, jacobians = [], []
        for side in (0, 1):
            frame_id = model.sole_frame_ids[side]
            current = data.oMf[frame_id]
            error = pin.log6(current.actInv(sole_targets[side])).vector
            local = pin.getFrameJacobian(pm, data, frame_id, pin.ReferenceFrame.LOCAL)
            errors.append(error)
            jacobians.append(pin.Jlog6(current.actInv(sole_targets[side]).inverse()) @ local)
        errors.append(np.asarray(target.com_xy_m) - data.com[0][:2])
        jacobians.append(data.Jcom[:2])
        base = data.oMf[base_frame]
        errors.append(-pin.log3(base.rotation))
        jacobians.append(
            pin.getFrameJacobian(pm, data, base_frame, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[3:]
        )
        errors.append(np.array([target.pelvis_height_m - base.translation[2]]))
        jacobians.append(
            pin.getFrameJacobian(pm, data, base_frame, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[2:3]
        )
        error = np.concatenate(errors)
        jacobian = np.vstack(jacobians)
        residual = float(np.max(np.abs(error)))
        if residual < tolerance:
            return SolvedPosture(model.leg_angles(q), q, residual, iteration)
        step = np.linalg.solve(jacobian.T @ jacobian + damping * np.eye(pm.nv), jacobian.T @ error)
        q = pin.integrate(pm, q, step)
    raise PostureError(
        f"posture IK did not converge in {max_iterations} iterations (residual {residual:.3g})"
    )


# The lab's "Init Walking" leg posture (psh117/dyros_jet, dyros_jet_gui task_window.cpp,
# on_button_walk_init_lowerbody_clicked), lab order, rad: hip roll +-2 deg, hip pitch -+2 deg,
# knee +-42 deg, ankle pitch -+40 deg, ankle roll -+2 deg (the right leg's pitch axes are -y).
# Feet flat (the pitch angles sum to zero, the roll angles too), soles 0.2556 m apart, pelvis
# 0.870 m above the ground; its CoM is 0.040 m ahead of the sole centres.
LAB_WALK_INIT_LEG_ANGLES_RAD: tuple[float, ...] = (
    0.0, 0.034906585, -0.034906585, 0.733038285, -0.6981317, -0.034906585,
    0.0, -0.034906585, 0.034906585, -0.733038285, 0.6981317, 0.034906585,
)  # fmt: skip

if len(LAB_WALK_INIT_LEG_ANGLES_RAD) != N_LEG_JOINTS:  # pragma: no cover - a typo guard
    raise AssertionError("LAB_WALK_INIT_LEG_ANGLES_RAD needs 12 entries")

# The walking-ready posture: the lab's "Init Walking" idea (bent knees, feet flat side by side,
# pelvis upright at the same height) with the CoM put over the middle of the two sole centres,
# as the start of a walk needs it (the lab's own angles leave it 0.040 m ahead). Solved with
# `solve_posture` from this target; the test suite re-solves it and checks every constraint.
WALKING_READY_TARGET = PostureTarget(
    left_sole_m=(0.0, 0.1278, 0.0),  # soles 0.2556 m apart, as in the lab's posture
    right_sole_m=(0.0, -0.1278, 0.0),
    com_xy_m=(0.0, 0.0),
    pelvis_height_m=0.87,  # the lab's posture: 0.8705 m
)
# Lab order, rad. In degrees: L 0, 1.820, -6.569, 42.225, -35.656, -1.820;
# R 0, -2.178, 6.546, -42.179, 35.633, 2.178 (the right leg's pitch axes are -y; the small
# left/right difference comes from the published masses: thighs' CoM x, hands). CoM 0.828 m
# above the ground, pelvis 0.034 m behind the sole centres.
WALKING_READY_LEG_ANGLES_RAD: tuple[float, ...] = (
    0.0, 0.0317718378, -0.1146555027, 0.7369626642, -0.6223071615, -0.0317718378,
    0.0, -0.0380199914, 0.1142455437, -0.7361605913, 0.6219150476, 0.0380199914,
)  # fmt: skip
