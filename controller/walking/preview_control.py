"""Kajita's ZMP preview control on the cart-table model (servo form, jerk input).

S. Kajita et al., "Biped Walking Pattern Generation by using Preview Control of Zero-Moment
Point", ICRA 2003, Sec. III-IV; the servo (integral) form and its preview gains are
T. Katayama et al., "Design of an optimal controller for a discrete-time system subject to
previewable demand", Int. J. Control 41(3), 1985.

Cart-table, per horizontal axis, sampled at dt with a piecewise-constant jerk u (Kajita (6)-(7)):

    x(k+1) = A x(k) + B u(k),   x = [p, p', p''],   p_zmp(k) = C x(k)
    A = [[1, dt, dt^2/2], [0, 1, dt], [0, 0, 1]],  B = [dt^3/6, dt^2/2, dt]',  C = [1, 0, -zc/g].

Servo form. With increments dx(k) = x(k) - x(k-1), du(k) = u(k) - u(k-1) and the tracking
error e(k) = p_zmp(k) - p_ref(k), the augmented system (Katayama) is

    [e; dx](k+1) = At [e; dx](k) + Bt du(k) - It dref(k+1),
    At = [[1, C A], [0, A]],  Bt = [C B; B],  It = [1; 0; 0; 0],

with the cost sum Qe e^2 + dx' Qx dx + R du^2 (Kajita: Qe = 1, Qx = 0, R = 1e-6). P solves the
DARE of (At, Bt, diag(Qe, Qx), R) (scipy.linalg.solve_discrete_are); with
W = (R + Bt' P Bt)^-1 and the closed loop Ac = At - Bt W Bt' P At, the gains are

    Gi = W Bt' P It,   Gx = W Bt' P [C A; A],
    Gp(1) = -Gi,  Gp(j) = W Bt' X(j-1),  X(1) = -Ac' P It,  X(j) = Ac' X(j-1)   (Kajita (10)-(12))

and the controller, summed over the ticks (Kajita (9)):

    u(k) = -Gi sum_{i<=k} e(i) - Gx x(k) - sum_{j=1}^{NL} Gp(j) p_ref(k+j).

Start-up. The summed form equals Katayama's incremental form with u(-1) = 0 and x at rest only
if the integral starts at s0 = -(Gx[0] + sum_j Gp(j)) p_ref(0) / Gi: the preview truncated at NL
does not sum exactly to -Gx[0], and s0 makes the rest state x(0) = [p_ref(0), 0, 0] an exact
equilibrium. The plan's initial rest, at least NL ticks long, makes the preview window see only
p_ref(0) at tick 0, so there is no start-up transient.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.lib.stride_tricks import sliding_window_view

STANDARD_GRAVITY_M_S2 = 9.81


@dataclass(frozen=True)
class CartTableParams:
    """The cart-table model: CoM height zc [m] (constant), gravity [m/s^2], period dt [s]."""

    com_height_m: float = 0.8
    gravity_mps2: float = STANDARD_GRAVITY_M_S2
    dt_s: float = 0.005

    def __post_init__(self) -> None:
        for name in ("com_height_m", "gravity_mps2", "dt_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be finite and > 0, got {value}")

    def matrices(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(A (3, 3), B (3,), C (3,)) of the sampled cart-table."""
        dt = self.dt_s
        a = np.array([[1.0, dt, dt * dt / 2.0], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
        b = np.array([dt**3 / 6.0, dt * dt / 2.0, dt])
        c = np.array([1.0, 0.0, -self.com_height_m / self.gravity_mps2])
        return a, b, c


@dataclass(frozen=True)
class PreviewWeights:
    """Cost weights: Qe on the ZMP error [1/m^2] (> 0), Qx on the state increments (>= 0, one
    scalar times I), R on the jerk increment (> 0). Defaults: Kajita 2003 (Qe = 1, Qx = 0,
    R = 1e-6)."""

    tracking_error_weight: float = 1.0
    state_increment_weight: float = 0.0
    jerk_increment_weight: float = 1e-6

    def __post_init__(self) -> None:
        if not (math.isfinite(self.tracking_error_weight) and self.tracking_error_weight > 0):
            raise ValueError(f"tracking_error_weight must be > 0, got {self.tracking_error_weight}")
        if not (math.isfinite(self.state_increment_weight) and self.state_increment_weight >= 0):
            raise ValueError(
                f"state_increment_weight must be >= 0, got {self.state_increment_weight}"
            )
        if not (math.isfinite(self.jerk_increment_weight) and self.jerk_increment_weight > 0):
            raise ValueError(f"jerk_increment_weight must be > 0, got {self.jerk_increment_weight}")


@dataclass(frozen=True)
class PreviewGains:
    """Gi (integral), Gx (3,) (state), Gp (NL,) (preview, Gp[j-1] multiplies p_ref(k+j));
    the servo system's closed-loop matrix (4, 4) and Riccati solution (4, 4) for analysis."""

    integral_gain: float
    state_gain: np.ndarray
    preview_gains: np.ndarray
    closed_loop_matrix: np.ndarray
    riccati_solution: np.ndarray
    model: CartTableParams

    @property
    def horizon_ticks(self) -> int:
        return int(self.preview_gains.shape[0])


def servo_system(model: CartTableParams) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(At (4, 4), Bt (4, 1), It (4, 1), Ft (4, 3)) of the servo form (module docstring)."""
    a, b, c = model.matrices()
    at = np.zeros((4, 4))
    at[0, 0] = 1.0
    at[0, 1:] = c @ a
    at[1:, 1:] = a
    bt = np.concatenate(([c @ b], b)).reshape(4, 1)
    it = np.array([[1.0], [0.0], [0.0], [0.0]])
    ft = np.vstack((c @ a, a))
    return at, bt, it, ft


def design_preview_controller(
    model: CartTableParams, weights: PreviewWeights, horizon_s: float
) -> PreviewGains:
    """Gains of the servo-form preview controller with an NL = horizon_s / dt tick preview."""
    n_preview = round(horizon_s / model.dt_s)
    if n_preview < 1 or abs(n_preview * model.dt_s - horizon_s) > 1e-9 * max(1.0, horizon_s):
        raise ValueError(
            f"horizon_s = {horizon_s} must be a whole number (>= 1) of periods dt = {model.dt_s}"
        )
    at, bt, it, ft = servo_system(model)
    q = np.diag([weights.tracking_error_weight] + [weights.state_increment_weight] * 3)
    r = np.array([[weights.jerk_increment_weight]])
    p = scipy.linalg.solve_discrete_are(at, bt, q, r)
    w = np.linalg.inv(r + bt.T @ p @ bt)
    gi = float((w @ bt.T @ p @ it)[0, 0])
    gx = (w @ bt.T @ p @ ft).ravel()
    ac = at - bt @ w @ bt.T @ p @ at
    gp = np.empty(n_preview)
    gp[0] = -gi
    x = -ac.T @ p @ it
    for j in range(1, n_preview):
        gp[j] = float((w @ bt.T @ x)[0, 0])
        x = ac.T @ x
    for array in (gx, gp, ac, p):
        array.setflags(write=False)
    return PreviewGains(gi, gx, gp, ac, p, model)


@dataclass(frozen=True)
class CartTableTrajectory:
    """The CoM trajectory the preview controller produces, per tick k = 0..N-1, per axis
    (columns x, y): position [m], velocity [m/s], acceleration [m/s^2], jerk input [m/s^3],
    and the cart-table's own ZMP C x(k) [m]."""

    position_m: np.ndarray
    velocity_mps: np.ndarray
    acceleration_mps2: np.ndarray
    jerk_mps3: np.ndarray
    zmp_m: np.ndarray


def preview_feedforward(gains: PreviewGains, zmp_reference_m: np.ndarray) -> np.ndarray:
    """sum_{j=1}^{NL} Gp(j) p_ref(k+j) for every tick (N, n_axes); beyond the reference's end
    the last value holds (the plan ends with a rest)."""
    n_preview = gains.horizon_ticks
    padded = np.concatenate(
        (zmp_reference_m, np.repeat(zmp_reference_m[-1:], n_preview, axis=0)), axis=0
    )
    windows = sliding_window_view(padded[1:], n_preview, axis=0)  # (N, n_axes, NL)
    return windows @ gains.preview_gains


def track_zmp_reference(gains: PreviewGains, zmp_reference_m: np.ndarray) -> CartTableTrajectory:
    """Run the preview controller over a whole ZMP reference (N, n_axes), starting at rest over
    p_ref(0) (module docstring: the integral starts at the value that makes this rest an
    equilibrium)."""
    reference = np.asarray(zmp_reference_m, dtype=float)
    if reference.ndim != 2 or reference.shape[0] < 1 or not np.all(np.isfinite(reference)):
        raise ValueError("zmp_reference_m must be a finite (N, n_axes) array with N >= 1")
    a, b, c = gains.model.matrices()
    gi, gx = gains.integral_gain, gains.state_gain
    feedforward = preview_feedforward(gains, reference)
    n_ticks, n_axes = reference.shape
    states = np.empty((n_ticks, 3, n_axes))
    jerk = np.empty((n_ticks, n_axes))
    state = np.zeros((3, n_axes))
    state[0] = reference[0]
    integral = -(gx[0] + gains.preview_gains.sum()) * reference[0] / gi
    for k in range(n_ticks):
        states[k] = state
        integral = integral + (c @ state - reference[k])
        u = -gi * integral - gx @ state - feedforward[k]
        jerk[k] = u
        state = a @ state + np.outer(b, u)
    zmp = np.einsum("i,kia->ka", c, states)
    return CartTableTrajectory(
        position_m=states[:, 0, :],
        velocity_mps=states[:, 1, :],
        acceleration_mps2=states[:, 2, :],
        jerk_mps3=jerk,
        zmp_m=zmp,
    )
