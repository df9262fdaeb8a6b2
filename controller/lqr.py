"""LQR tracking controller in derivative form, Kim et al., ICRA 2018, Sec. III-C, (21)-(24).

Continuous design, as in the paper. Differentiating (20) and appending the tracking error
e = y - theta_d (theta_d slowly varying, d theta_d/dt ~ 0) gives the augmented system (21)

    d/dt [e; dx/dt] = [[0, C], [0, A]] [e; dx/dt] + [[0], [B]] duc/dt,

the cost (22) J = int e' Qe e + (dx/dt)' Qx (dx/dt) + (duc/dt)' R (duc/dt) dt, the Riccati
equation (23) A'S + SA - S B R^-1 B'S + Q = 0 and the feedback (24) duc/dt = -R^-1 B'S [e; dx/dt].

Discrete design, what the loop runs (as the lab's code does). With the plant sampled at the loop
period, x(k+1) = Ad x(k) + Bd u(k), the increments dx(k) = x(k) - x(k-1) and
duc(k) = uc(k) - uc(k-1) obey dx(k+1) = Ad dx(k) + Bd duc(k), and e(k+1) = e(k) + C dx(k+1) for a
constant reference, so

    [e; dx](k+1) = [[I, C Ad], [0, Ad]] [e; dx](k) + [[C Bd], [Bd]] duc(k),

and scipy.linalg.solve_discrete_are gives P and duc(k) = -(R + B'PB)^-1 B'PA [e(k); dx(k)]. uc is
the running sum of duc: the error weight makes it an integral controller (gain per tick on e, an
integral gain of error_gain / dt). Three designs (`LqrDesign`):

    "euler"            Ad = I + A dt, Bd = B dt (the lab's code), Q and R applied per tick
    "zoh"              exact sampling of (20) for a goal held over the tick, Q and R per tick
    "continuous-cost"  the paper's cost (22) itself, integrated exactly over each tick

The per-tick weights are NOT the paper's cost (22). Summing (22) over ticks with dx ~ (dx/dt) dt
and duc ~ (duc/dt) dt gives J ~ (1/dt) sum_k (Qe dt^2 e'e + Qx dx'dx + R duc'duc): the per-tick
problem equivalent to (22) weights the error by Qe dt^2 against the increments. "euler" and "zoh"
weight it by Qe, 1/dt^2 = 40,000 times more at 200 Hz. So they are much stiffer integrators than
(22) asks for. For one joint with I_link = 0.376 kg m^2 (K 2000, D 100, Kp 10, Qe 10, Qx 1, R 1,
200 Hz; tests/controller/test_lqr_designs.py):

    design           Ke/tick  Ke/dt [1/s]  Kx on [d th_m, d th_j, d dth_j]  rho     tau_dom
    euler (the lab)  0.2170   43.4         [0.998,  0.671, -0.0114]         0.9149  56 ms
    zoh              0.3866   77.3         [0.950,  2.559,  0.0402]         0.9148  56 ms
    continuous-cost  0.00258  0.516        [0.945, -1.444,  0.0635]         0.9924  0.657 s
    (22) continuous  -        3.162 = sqrt(Qe/R); dominant poles -1.522 +- 0.911j: 0.657 s

(rho: spectral radius of the designed closed loop; tau_dom = -dt / ln(rho).) The continuous
design's error gain is sqrt(Qe/R) exactly: the (1,1) block of (23) reads Ke' R Ke = Qe, because
the error is a pure integrator of C dx/dt.

"continuous-cost": (21) sampled with duc/dt held over each tick (Van Loan's method, C. F. Van
Loan, "Computing integrals involving the matrix exponential", IEEE TAC 23(3), 1978): with
F = [[A_bar, B_bar], [0, 0]] and W = blockdiag(Q, R),

    expm([[-F', W], [0, F]] dt) = [[., G12], [0, G22]],  G22 = expm(F dt) = [[Phi, Gamma], [0, I]],
    int_0^dt z' W z dt = z(0)' (G22' G12) z(0) = xi' Qd xi + 2 xi' N w + w' Rd w,  z = [xi; w],

and the DARE with the cross term N gives w(k) = -K xi(k) on xi = [e; dx/dt], run as
duc(k) = dt w(k) with dx/dt ~ dx(k) / dt, i.e. error_gain = K_e dt, state_increment_gain = K_x.
As dt -> 0 it tends to the continuous design (Ke/dt -> sqrt(Qe/R)); at 200 Hz its dominant pole is
already the continuous one (-1.522 +- 0.911j to 1e-4), while its error gain is 6x below sqrt(10):
the continuous optimum leans on a -2,671 rad/s pole that a 5 ms sample cannot realise.
What it means for the DOB: in the accumulated reading the static yield is Kdist d / Ke (see
`controller.composition`), 84x larger than with the lab's Ke: the per-tick weights are what make
the lab's DOB hold a load at all.

Why not the continuous gain itself at 200 Hz: its fastest closed-loop pole lies at -2,671 rad/s
(Qx = I) for I_link = 0.376 kg m^2, far beyond pi/dt = 628 rad/s; implemented as
duc(k) = dt * duc/dt it is unstable (spectral radius 2.99 with Qx = I, 13.0 with Q = 10 I on all
states, tests/controller/test_closed_loop.py). The continuous design stays for analysis.

Closed kinematic chains (coupling "closed-chain"). With both feet on the ground Sm of (19) is
singular: DYROS-JET's legs have 18 velocities and 12 contact constraints, so Sm (12 x 12) has
rank 6 (walking-ready posture: eigenvalues 3.33, 2.38, 1.69, 1.50, 0.101, 0.038 and six zeros).
In its null space no joint torque moves a link; there (20) carries link states without dynamics
and the augmented error of (21) is an integrator no input reaches, so "full" has no stabilising
DARE. "diagonal" (the lab's) runs anyway, and on the coupled plant it (a) integrates whatever
part of the error lies in that null space (encoder offsets, contact compliance, the reference's
closure) into goals that ramp while the links stay (Jordan blocks at z = 1: internal forces
grow), and (b) designs each joint on 1 / Sm_ii, the inertia it would drive if every other joint
were limp; in the chain the others hold, and the sagittal sway mode is unstable (z = 1.0043 at
3.4 Hz with the paper's servo model; tests/controller/test_lqr_closed_chain.py).
"closed-chain" designs on the chain's own coordinates: V (n x r) an orthonormal basis of the
range of Sm (`motion_subspace`), theta_j = V xi, state [theta_m (n); xi (r); dxi/dt (r)]
(`closed_chain_state_space`, exact: that subspace is invariant under (20)), error V'e. For every
motion the chain allows, xi'xi = theta_j'theta_j, so the cost is the paper's (22) on the motions
the robot can make; V'e = 0 is reachable (the link goes to the closure-consistent posture
nearest to the reference), the rest of the error is left to the springs. The gain maps back to
[e; dx] as n x 4n, error gain K_e V'. With a nonsingular Sm (one foot, the testbed) it is the
"full" design.

Weights. The paper (Sec. IV-A): "Q and R ... are the diagonal matrix of 10 and 1". We read it
as the lab's code does: Qe = 10 I on the error, Qx = 1 I on the state increments, R = 1 I
(`LqrWeights()` defaults). The other reading, Q = 10 I on all 4n states, is
`LqrWeights(state_increment_weight=10.0)`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np
import scipy.linalg

from controller.model import (
    Discretisation,
    FlexibleJointParams,
    StateSpace,
    discretise,
    flexible_joint_state_space,
    validate_sm,
)

Coupling = Literal["full", "diagonal", "closed-chain"]
COUPLINGS: tuple[str, ...] = get_args(Coupling)
LqrDesign = Literal["euler", "zoh", "continuous-cost"]
LQR_DESIGNS: tuple[str, ...] = get_args(LqrDesign)


def servo_discretisation(design: LqrDesign) -> Discretisation:
    """The sampling of the nominal servo (4) that goes with an LQR design (the DOB's Pn^-1):
    the lab's Euler with "euler", the exact ZOH otherwise."""
    if design not in LQR_DESIGNS:
        raise ValueError(f"LQR design must be one of {LQR_DESIGNS}, got {design!r}")
    return "euler" if design == "euler" else "zoh"


@dataclass(frozen=True)
class LqrWeights:
    """Cost weights of (22), each times an identity matrix.

    tracking_error_weight: Qe on e [1/rad^2] (> 0); state_increment_weight: Qx on the state
    increments (>= 0); input_increment_weight: R on the input increment (> 0). Defaults: the
    paper's "10 and 1" as the lab coded them (Qe = 10 I, Qx = I, R = I).
    """

    tracking_error_weight: float = 10.0
    state_increment_weight: float = 1.0
    input_increment_weight: float = 1.0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.tracking_error_weight) and self.tracking_error_weight > 0):
            raise ValueError(
                f"tracking_error_weight must be finite and > 0, got {self.tracking_error_weight}"
            )
        if not (np.isfinite(self.state_increment_weight) and self.state_increment_weight >= 0):
            raise ValueError(
                f"state_increment_weight must be finite and >= 0, got {self.state_increment_weight}"
            )
        if not (np.isfinite(self.input_increment_weight) and self.input_increment_weight > 0):
            raise ValueError(
                f"input_increment_weight must be finite and > 0, got {self.input_increment_weight}"
            )

    def matrices(self, n_joints: int) -> tuple[np.ndarray, np.ndarray]:
        """Q = blockdiag(Qe (n), Qx (3n)) and R (n) for n joints."""
        q = np.diag(
            np.concatenate(
                [
                    np.full(n_joints, self.tracking_error_weight),
                    np.full(3 * n_joints, self.state_increment_weight),
                ]
            )
        )
        r = self.input_increment_weight * np.eye(n_joints)
        return q, r


@dataclass(frozen=True)
class LqrSolution:
    """gain K, Riccati solution S (or P) and the eigenvalues of the designed closed loop."""

    gain: np.ndarray
    riccati: np.ndarray
    closed_loop_eigenvalues: np.ndarray


def _check_lqr_arguments(
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
    _check_lqr_arguments(a, b, q, r)
    try:
        riccati = scipy.linalg.solve_continuous_are(a, b, q, r)
    except (np.linalg.LinAlgError, ValueError) as error:
        raise ValueError(
            f"no stabilising continuous Riccati solution ((A, B) not stabilisable or "
            f"(A, Q) has unobservable modes on the imaginary axis): {error}"
        ) from error
    gain = np.linalg.solve(r, b.T @ riccati)
    return LqrSolution(gain, riccati, np.linalg.eigvals(a - b @ gain))


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
    _check_lqr_arguments(a, b, q, r, cross_weight)
    try:
        riccati = scipy.linalg.solve_discrete_are(a, b, q, r, s=cross_weight)
    except (np.linalg.LinAlgError, ValueError) as error:
        raise ValueError(
            f"no stabilising discrete Riccati solution ((A, B) not stabilisable or "
            f"(A, Q) has unobservable modes on the unit circle): {error}"
        ) from error
    coupling = b.T @ riccati @ a
    if cross_weight is not None:
        coupling = coupling + cross_weight.T
    gain = np.linalg.solve(r + b.T @ riccati @ b, coupling)
    return LqrSolution(gain, riccati, np.linalg.eigvals(a - b @ gain))


@dataclass(frozen=True)
class SampledQuadraticCost:
    """A continuous system and cost sampled with the input held over each period dt:
    x(k+1) = phi x(k) + gamma w(k), and, exactly,
    int_{k dt}^{(k+1) dt} x'Qx + w'Rw dt = x(k)' Qd x(k) + 2 x(k)' N w(k) + w(k)' Rd w(k)."""

    phi: np.ndarray
    gamma: np.ndarray
    state_weight: np.ndarray
    cross_weight: np.ndarray
    input_weight: np.ndarray


def sample_quadratic_cost(
    a: np.ndarray, b: np.ndarray, q: np.ndarray, r: np.ndarray, dt_s: float
) -> SampledQuadraticCost:
    """Van Loan's method (see the module docstring): one matrix exponential gives the sampled
    system and the exact integral of the cost over a period."""
    _check_lqr_arguments(a, b, q, r)
    if not (np.isfinite(dt_s) and dt_s > 0):
        raise ValueError(f"dt_s must be finite and > 0, got {dt_s}")
    n_states, n_inputs = b.shape
    size = n_states + n_inputs
    f = np.zeros((size, size))
    f[:n_states, :n_states] = a
    f[:n_states, n_states:] = b
    w = scipy.linalg.block_diag(q, r)
    van_loan = scipy.linalg.expm(np.block([[-f.T, w], [np.zeros((size, size)), f]]) * dt_s)
    transition = van_loan[size:, size:]  # expm(F dt)
    weight = transition.T @ van_loan[:size, size:]
    weight = 0.5 * (weight + weight.T)
    return SampledQuadraticCost(
        phi=transition[:n_states, :n_states],
        gamma=transition[:n_states, n_states:],
        state_weight=weight[:n_states, :n_states],
        cross_weight=weight[:n_states, n_states:],
        input_weight=weight[n_states:, n_states:],
    )


def augmented_continuous(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, ...]:
    """(21): A_bar = [[0, C], [0, A]], B_bar = [[0], [B]] on the state [e; dx/dt]."""
    n_outputs, n_states = c.shape
    n_inputs = b.shape[1]
    a_bar = np.block([[np.zeros((n_outputs, n_outputs)), c], [np.zeros((n_states, n_outputs)), a]])
    b_bar = np.vstack([np.zeros((n_outputs, n_inputs)), b])
    return a_bar, b_bar


def augmented_discrete(
    a_d: np.ndarray, b_d: np.ndarray, c: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """A_aug = [[I, C Ad], [0, Ad]], B_aug = [[C Bd], [Bd]] on the state [e(k); dx(k)]."""
    n_outputs, n_states = c.shape
    a_aug = np.block([[np.eye(n_outputs), c @ a_d], [np.zeros((n_states, n_outputs)), a_d]])
    b_aug = np.vstack([c @ b_d, b_d])
    return a_aug, b_aug


@dataclass(frozen=True)
class TrackingGain:
    """duc(k) = -(error_gain e(k) + state_increment_gain dx(k)), per tick.

    error_gain: n x n [rad of input per tick per rad of error]; state_increment_gain: n x 3n on
    dx = [d theta_m; d theta_j; d dtheta_j]. `spectral_radius`: of the designed nominal closed
    loop A_aug - B_aug K (NaN when the gain was not designed on a discrete model).
    """

    error_gain: np.ndarray
    state_increment_gain: np.ndarray
    dt_s: float
    spectral_radius: float

    def __post_init__(self) -> None:
        n = self.error_gain.shape[0]
        if self.error_gain.shape != (n, n) or self.state_increment_gain.shape != (n, 3 * n):
            raise ValueError(
                f"error_gain must be n x n and state_increment_gain n x 3n, got "
                f"{self.error_gain.shape} and {self.state_increment_gain.shape}"
            )
        for gain in (self.error_gain, self.state_increment_gain):
            gain.flags.writeable = False

    @property
    def n_joints(self) -> int:
        return int(self.error_gain.shape[0])

    @property
    def stacked(self) -> np.ndarray:
        """[error_gain, state_increment_gain]: n x 4n on [e; dx]."""
        return np.hstack([self.error_gain, self.state_increment_gain])

    @property
    def integral_gain_per_s(self) -> np.ndarray:
        """error_gain / dt: the integral gain of uc on the tracking error [1/s]."""
        return self.error_gain / self.dt_s

    @property
    def dominant_time_constant_s(self) -> float:
        """-dt / ln(spectral radius): the slowest mode of the designed loop [s] (NaN if unknown)."""
        if not 0.0 < self.spectral_radius < 1.0:
            return float("nan")
        return -self.dt_s / math.log(self.spectral_radius)


def design_continuous_tracking_lqr(
    params: FlexibleJointParams, sm: np.ndarray, weights: LqrWeights
) -> LqrSolution:
    """The paper's design: (21)-(24) on the continuous model (20). Gain is n x 4n on [e; dx/dt]."""
    system = flexible_joint_state_space(params, sm)
    a_bar, b_bar = augmented_continuous(system.a, system.b, system.c)
    q, r = weights.matrices(params.n_joints)
    return continuous_lqr(a_bar, b_bar, q, r)


def sample_continuous_gain(solution: LqrSolution, dt_s: float) -> TrackingGain:
    """The continuous gain run at period dt_s: duc(k) = dt * duc/dt with dx/dt ~ dx(k) / dt.

    This is what "the paper's gain at 200 Hz" means; it is kept for analysis only (unstable).
    """
    n = solution.gain.shape[0]
    return TrackingGain(
        error_gain=solution.gain[:, :n] * dt_s,
        state_increment_gain=solution.gain[:, n:].copy(),
        dt_s=float(dt_s),
        spectral_radius=float("nan"),
    )


def _design_discrete_coupled(
    params: FlexibleJointParams,
    sm: np.ndarray,
    dt_s: float,
    weights: LqrWeights,
    design: LqrDesign,
    continuous: StateSpace | None = None,
) -> tuple[np.ndarray, float]:
    """Gain per tick on [e; dx] and the designed loop's spectral radius.

    continuous: the model to design on (default (20) with this Sm); the closed-chain design
    passes (20) restricted to the chain's motion subspace, with its own error and state sizes.
    """
    n = params.n_joints
    if continuous is None:
        continuous = flexible_joint_state_space(params, sm)
    n_errors, n_states = continuous.c.shape
    q = np.diag(
        np.concatenate(
            [
                np.full(n_errors, weights.tracking_error_weight),
                np.full(n_states, weights.state_increment_weight),
            ]
        )
    )
    r = weights.input_increment_weight * np.eye(n)
    if design == "continuous-cost":
        a_bar, b_bar = augmented_continuous(continuous.a, continuous.b, continuous.c)
        cost = sample_quadratic_cost(a_bar, b_bar, q, r, dt_s)
        solution = discrete_lqr(
            cost.phi, cost.gamma, cost.state_weight, cost.input_weight, cost.cross_weight
        )
        # w = duc/dt on [e; dx/dt]  ->  duc(k) = dt w = -(K_e dt) e - K_x dx(k)
        gain = solution.gain.copy()
        gain[:, :n_errors] *= dt_s
    else:
        system = discretise(continuous, dt_s, servo_discretisation(design))
        a_aug, b_aug = augmented_discrete(system.a, system.b, system.c)
        solution = discrete_lqr(a_aug, b_aug, q, r)
        gain = solution.gain
    return gain, float(np.max(np.abs(solution.closed_loop_eigenvalues)))


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


def closed_chain_state_space(
    params: FlexibleJointParams, sm: np.ndarray, basis: np.ndarray
) -> StateSpace:
    """(20) on the chain's own coordinates: x_r = [theta_m (n); xi (r); dxi/dt (r)] with
    theta_j = V xi (V = `basis`, orthonormal, spanning the range of Sm), y = xi.

    The link states of (20) in the null space of Sm have no dynamics (their acceleration is
    Sm tau = 0 whatever tau), so the subspace theta_j, dtheta_j in range(V) is invariant and
    x = T x_r with T = blockdiag(I, V, V) gives A_r = T' A T, B_r = T' B, C_r = V' C T exactly.
    """
    full = flexible_joint_state_space(params, sm)
    n = params.n_joints
    rank = basis.shape[1]
    transform = np.zeros((3 * n, n + 2 * rank))
    transform[:n, :n] = np.eye(n)
    transform[n : 2 * n, n : n + rank] = basis
    transform[2 * n :, n + rank :] = basis
    return StateSpace(
        a=transform.T @ full.a @ transform,
        b=transform.T @ full.b,
        c=basis.T @ full.c @ transform,
    )


def _design_closed_chain(
    params: FlexibleJointParams,
    sm: np.ndarray,
    dt_s: float,
    weights: LqrWeights,
    design: LqrDesign,
) -> tuple[np.ndarray, float]:
    """The coupled design on the motion subspace, mapped back to [e; dx] (n x 4n)."""
    n = params.n_joints
    basis = motion_subspace(sm)
    rank = basis.shape[1]
    reduced = closed_chain_state_space(params, sm, basis)
    gain_r, radius = _design_discrete_coupled(params, sm, dt_s, weights, design, reduced)
    # gain_r acts on [V'e (r); d theta_m (n); V' d theta_j (r); V' d dtheta_j (r)]
    gain = np.zeros((n, 4 * n))
    gain[:, :n] = gain_r[:, :rank] @ basis.T
    gain[:, n : 2 * n] = gain_r[:, rank : rank + n]
    gain[:, 2 * n : 3 * n] = gain_r[:, rank + n : 2 * rank + n] @ basis.T
    gain[:, 3 * n :] = gain_r[:, 2 * rank + n :] @ basis.T
    return gain, radius


def design_discrete_tracking_lqr(
    params: FlexibleJointParams,
    sm: np.ndarray,
    dt_s: float,
    weights: LqrWeights | None = None,
    method: LqrDesign = "zoh",
    coupling: Coupling = "full",
) -> TrackingGain:
    """The gain the loop runs: the discrete derivative-form LQR at period dt_s.

    method: "zoh" (exact sampling of (20) for a goal held over the tick, Q and R per tick;
    default), "euler" (the lab's forward Euler, Q and R per tick; see
    `controller.model.discretise` for where it breaks down) or "continuous-cost" (the paper's
    cost (22) integrated over each tick; see the module docstring for what each weighs).
    coupling: "full" solves one 4n-state problem with the whole Sm; "diagonal" keeps only the
    diagonal of Sm (as the lab's code does), solves n independent 4-state problems and stacks
    them (each gain block is then diagonal). With a diagonal Sm both give the same gain.
    "closed-chain" solves the coupled problem on the motions the chain allows (the range of
    Sm, rank r): state [V'e; d theta_m; V' d theta_j; V' d dtheta_j] (3r + n), see the
    module docstring; with a nonsingular Sm it is the "full" design (same gain).
    """
    weights = weights if weights is not None else LqrWeights()
    if method not in LQR_DESIGNS:
        raise ValueError(f"LQR design must be one of {LQR_DESIGNS}, got {method!r}")
    n = params.n_joints
    sm = validate_sm(sm, n)
    if coupling == "full":
        gain, radius = _design_discrete_coupled(params, sm, dt_s, weights, method)
    elif coupling == "closed-chain":
        gain, radius = _design_closed_chain(params, sm, dt_s, weights, method)
    elif coupling == "diagonal":
        gain = np.zeros((n, 4 * n))
        radius = 0.0
        for joint in range(n):
            joint_gain, joint_radius = _design_discrete_coupled(
                params.joint(joint), sm[joint : joint + 1, joint : joint + 1], dt_s, weights, method
            )
            # 1-joint gain is [e, theta_m, theta_j, dtheta_j]; place it in the stacked layout.
            for block in range(4):
                gain[joint, block * n + joint] = joint_gain[0, block]
            radius = max(radius, joint_radius)
    else:
        raise ValueError(f"coupling must be one of {COUPLINGS}, got {coupling!r}")
    return TrackingGain(
        error_gain=gain[:, :n].copy(),
        state_increment_gain=gain[:, n:].copy(),
        dt_s=float(dt_s),
        spectral_radius=radius,
    )
