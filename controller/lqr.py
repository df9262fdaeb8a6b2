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

Designs on other models (the closed chain of two feet on the ground, the servo's own cascade,
the lab's per-joint problems solved as one batch) are in `controller.lqr_designs`; the Riccati
solvers in `controller.riccati`.

Weights. The paper (Sec. IV-A): "Q and R ... are the diagonal matrix of 10 and 1". We read it
as the lab's code does: Qe = 10 I on the error, Qx = 1 I on the state increments, R = 1 I
(`LqrWeights()` defaults). The other reading, Q = 10 I on all 4n states, is
`LqrWeights(state_increment_weight=10.0)`.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from controller.model import (
    Discretisation,
    FlexibleJointParams,
    StateSpace,
    discretise,
    flexible_joint_state_space,
)
from controller.riccati import (
    LqrSolution,
    check_lqr_arguments,
    continuous_lqr,
    discrete_lqr,
    discrete_lqr_batch,
)


class Coupling(enum.StrEnum):
    """What of Sm the LQR is designed on: all of it, its diagonal, or the closed chain's."""

    FULL = "full"
    DIAGONAL = "diagonal"
    CLOSED_CHAIN = "closed-chain"


COUPLINGS: tuple[str, ...] = tuple(member.value for member in Coupling)


class LqrDesign(enum.StrEnum):
    """How the LQR is designed: forward Euler (the lab's), zero-order hold, or the paper's
    continuous cost (22) over each tick."""

    EULER = "euler"
    ZOH = "zoh"
    CONTINUOUS_COST = "continuous-cost"


LQR_DESIGNS: tuple[str, ...] = tuple(member.value for member in LqrDesign)


def servo_discretisation(design: LqrDesign) -> Discretisation:
    """The sampling of the nominal servo (4) that goes with an LQR design (the DOB's Pn^-1):
    the lab's Euler with "euler", the exact ZOH otherwise."""
    if design not in LQR_DESIGNS:
        raise ValueError(f"LQR design must be one of {LQR_DESIGNS}, got {design!r}")
    return Discretisation.EULER if design == LqrDesign.EULER else Discretisation.ZOH


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
    check_lqr_arguments(a, b, q, r)
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
    """duc(k) = -(error_gain e(k) + state_increment_gain dx(k) [+ K_w d omega_m(k)]), per tick.

    error_gain: n x n [rad of input per tick per rad of error]; state_increment_gain: n x 3n on
    dx = [d theta_m; d theta_j; d dtheta_j]. `spectral_radius`: of the designed nominal closed
    loop A_aug - B_aug K (NaN when the gain was not designed on a discrete model).
    motor_velocity_increment_gain: K_w (n x n) on the increment of the motor velocity, for a
        design on a servo model that has the motor velocity as a state (the H54 cascade,
        `controller.servo_cascade`); None: the paper's model (4) has none.
    dob_gain_scale: per joint, what the DOB's Kdist is multiplied by while this gain runs
        ("paper-yield", see `controller.lqr_designs`); None: Kdist as given.
    """

    error_gain: np.ndarray
    state_increment_gain: np.ndarray
    dt_s: float
    spectral_radius: float
    motor_velocity_increment_gain: np.ndarray | None = None
    dob_gain_scale: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = self.error_gain.shape[0]
        if self.error_gain.shape != (n, n) or self.state_increment_gain.shape != (n, 3 * n):
            raise ValueError(
                f"error_gain must be n x n and state_increment_gain n x 3n, got "
                f"{self.error_gain.shape} and {self.state_increment_gain.shape}"
            )
        velocity = self.motor_velocity_increment_gain
        if velocity is not None and velocity.shape != (n, n):
            raise ValueError(f"motor_velocity_increment_gain must be n x n, got {velocity.shape}")
        scale = self.dob_gain_scale
        if scale is not None and (scale.shape != (n,) or not np.all(np.isfinite(scale))):
            raise ValueError(f"dob_gain_scale must be {n} finite factors, got {scale}")
        for gain in (self.error_gain, self.state_increment_gain, velocity, scale):
            if gain is not None:
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


@dataclass(frozen=True)
class ModelDesign:
    """One discrete tracking design on a continuous model (`design_on_model`).

    gain: n_inputs x (n_errors + n_states) per tick on [e; dx]; spectral_radius: of the designed
    loop A_aug - B_aug K; riccati: its Riccati solution."""

    gain: np.ndarray
    spectral_radius: float
    riccati: np.ndarray


def design_on_model(
    continuous: StateSpace,
    dt_s: float,
    weights: LqrWeights,
    design: LqrDesign,
    reference_solver: bool = False,
) -> ModelDesign:
    """The discrete derivative-form design (module docstring) on any continuous model
    dx/dt = A x + B u, y = C x: errors e = y - y_d (rows of C), Q = blockdiag(Qe I, Qx I),
    R = r I; solved by the doubling algorithm (`controller.riccati.discrete_lqr_batch`), or by
    scipy's QZ solver with `reference_solver` (the product before; for checks and benches)."""
    if design not in LQR_DESIGNS:
        raise ValueError(f"LQR design must be one of {LQR_DESIGNS}, got {design!r}")
    n_errors, n_states = continuous.c.shape
    n_inputs = continuous.b.shape[1]
    q = np.diag(
        np.concatenate(
            [
                np.full(n_errors, weights.tracking_error_weight),
                np.full(n_states, weights.state_increment_weight),
            ]
        )
    )
    r = weights.input_increment_weight * np.eye(n_inputs)
    if design == LqrDesign.CONTINUOUS_COST:
        a_bar, b_bar = augmented_continuous(continuous.a, continuous.b, continuous.c)
        cost = sample_quadratic_cost(a_bar, b_bar, q, r, dt_s)
        # the cross term folded into the state matrix: u = v - Rd^-1 N' x
        fold = np.linalg.solve(cost.input_weight, cost.cross_weight.T)
        a_aug = cost.phi - cost.gamma @ fold
        b_aug = cost.gamma
        q_aug = cost.state_weight - cost.cross_weight @ fold
        q_aug = 0.5 * (q_aug + q_aug.T)
        r_aug = cost.input_weight
    else:
        system = discretise(continuous, dt_s, servo_discretisation(design))
        a_aug, b_aug = augmented_discrete(system.a, system.b, system.c)
        q_aug, r_aug, fold = q, r, None
    if reference_solver:
        solution = discrete_lqr(a_aug, b_aug, q_aug, r_aug)
    else:
        check_lqr_arguments(a_aug, b_aug, q_aug, r_aug)
        batch = discrete_lqr_batch(a_aug[None], b_aug[None], q_aug[None], r_aug[None])
        solution = LqrSolution(batch.gain[0], batch.riccati[0], batch.closed_loop_eigenvalues[0])
    gain = solution.gain if fold is None else solution.gain + fold
    if (
        design == LqrDesign.CONTINUOUS_COST
    ):  # w = duc/dt on [e; dx/dt]: duc(k) = -(K_e dt) e - K_x dx(k)
        gain = gain.copy()
        gain[:, :n_errors] *= dt_s
    radius = float(np.max(np.abs(solution.closed_loop_eigenvalues)))
    return ModelDesign(gain, radius, solution.riccati)
