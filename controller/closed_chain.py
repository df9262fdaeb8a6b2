"""The closed kinematic chain of two feet on the ground: the model (20) on the motions it allows.

With both feet on the ground Sm of (19) is singular: DYROS-JET's legs have 18 velocities and 12
contact constraints, so Sm (12 x 12) has rank 6 (walking-ready posture: eigenvalues 3.33, 2.38,
1.69, 1.50, 0.101, 0.038 and six zeros). In its null space no joint torque moves a link; there
(20) carries link states without dynamics and the augmented error of (21) is an integrator no
input reaches, so "full" has no stabilising DARE. "diagonal" (the lab's) runs anyway, and on
the coupled plant it (a) integrates whatever part of the error lies in that null space (encoder
offsets, contact compliance, the reference's closure) into goals that ramp while the links
stay (Jordan blocks at z = 1: internal forces grow), and (b) designs each joint on 1 / Sm_ii,
the inertia it would drive if every other joint were limp; in the chain the others hold, and
the sagittal sway mode is unstable (z = 1.0043 at 3.4 Hz with the paper's servo model;
tests/controller/test_lqr_closed_chain.py).

"closed-chain" designs on the chain's own coordinates: V (n x r) an orthonormal basis of the
range of Sm (`motion_subspace`), theta_j = V xi, the link states (theta_j, dtheta_j) replaced by
(xi, dxi/dt), the motor states kept (`chain_coordinates`, exact: the subspace is invariant under
the model, whatever the servo model in front of the gear), error V'e. For every motion the chain
allows, xi'xi = theta_j'theta_j, so the cost is the paper's (22) on the motions the robot can
make; V'e = 0 is reachable (the link goes to the closure-consistent posture nearest to the
reference), the rest of the error is left to the springs. The gain maps back to [e; dx]
(`gain_from_chain`), error gain K_e V'. With a nonsingular Sm (one foot, the testbed) it is the
"full" design.
"""

from __future__ import annotations

import numpy as np

from controller.model import StateSpace

# Eigenvalues of Sm below this fraction of its largest are the closed chain's constrained
# directions (exactly zero in theory; ~1e-15 relative from the KKT inverse in practice, while
# DYROS-JET's slowest free mode in double support is 0.038 / 3.3 ~ 1e-2 of the largest).
MOTION_SUBSPACE_RTOL = 1e-8


def motion_subspace(sm: np.ndarray, rtol: float = MOTION_SUBSPACE_RTOL) -> np.ndarray:
    """Orthonormal basis V (n x r) of the range of Sm: the joint motions the chain allows.

    Sm = S M^-1 (I - Pc) S^T of (19) maps joint torques to joint accelerations; with contacts
    that close a chain (two feet on the ground) it is singular, and its range is the set of
    joint velocities compatible with the contacts (S times the null space of Jc); its null
    space holds the directions no joint torque can move (they only load the chain).
    """
    matrix = np.asarray(sm, dtype=float)
    if not (np.isfinite(rtol) and 0 < rtol < 1):
        raise ValueError(f"rtol must be in (0, 1), got {rtol}")
    eigenvalues, vectors = np.linalg.eigh(0.5 * (matrix + matrix.T))
    largest = float(np.max(eigenvalues))
    if largest <= 0:
        raise ValueError("Sm has no positive eigenvalue: no joint motion is possible")
    if np.min(eigenvalues) < -rtol * largest:
        raise ValueError(f"Sm must be positive semi-definite, got eigenvalue {eigenvalues.min()}")
    return vectors[:, eigenvalues > rtol * largest]


def chain_coordinates(full: StateSpace, basis: np.ndarray, n_motor_states: int) -> StateSpace:
    """A model x = [motor states (n_motor_states); theta_j (n); dtheta_j (n)], y = theta_j, on
    the chain's coordinates x_r = [motor states; xi (r); dxi/dt (r)] with theta_j = V xi.

    The link states in the null space of Sm have no dynamics (their acceleration is Sm tau = 0
    whatever tau), so the subspace theta_j, dtheta_j in range(V) is invariant and x = T x_r with
    T = blockdiag(I, V, V) gives A_r = T' A T, B_r = T' B, C_r = V' C T exactly.
    """
    n, rank = basis.shape
    m = n_motor_states
    transform = np.zeros((m + 2 * n, m + 2 * rank))
    transform[:m, :m] = np.eye(m)
    transform[m : m + n, m : m + rank] = basis
    transform[m + n :, m + rank :] = basis
    return StateSpace(
        a=transform.T @ full.a @ transform,
        b=transform.T @ full.b,
        c=basis.T @ full.c @ transform,
    )


def gain_from_chain(gain_r: np.ndarray, basis: np.ndarray, n_motor_states: int) -> np.ndarray:
    """A gain on [V'e (r); motor increments; V' d theta_j (r); V' d dtheta_j (r)] as the gain
    on [e (n); motor increments; d theta_j (n); d dtheta_j (n)]."""
    n, rank = basis.shape
    m = n_motor_states
    gain = np.zeros((gain_r.shape[0], n + m + 2 * n))
    gain[:, :n] = gain_r[:, :rank] @ basis.T
    gain[:, n : n + m] = gain_r[:, rank : rank + m]
    gain[:, n + m : 2 * n + m] = gain_r[:, rank + m : 2 * rank + m] @ basis.T
    gain[:, 2 * n + m :] = gain_r[:, 2 * rank + m :] @ basis.T
    return gain
