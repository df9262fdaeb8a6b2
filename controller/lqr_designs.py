"""The gains the loop runs: the derivative-form LQR of Sec. III-C, (21)-(24), on a chosen model.

Three choices, each typed, each orthogonal to the others:

    coupling      "full"          one problem on the whole Sm of (19)
                  "diagonal"      the lab's: Sm's diagonal only, n one-joint problems (each gain
                                  block diagonal), solved as one batch
                  "closed-chain"  the whole Sm on the motions the chain allows
                                  (`controller.closed_chain`; "full" when Sm is nonsingular)
    servo model   "first-order"   the paper's (4): d theta_m/dt = Kp (u - theta_m)
                  "cascade"       the actuator's position/velocity cascade with its rotor
                                  (`controller.servo_cascade`): its finite static stiffness
    design        "euler" | "zoh" | "continuous-cost"  (controller/lqr.py says what each weighs)

Cost per design (measured side by side, `hil bench loop --robot dyros-jet`, docs/humanoid.md):
"diagonal" builds the n one-joint problems as stacked arrays and solves them in one batch
(`controller.riccati.discrete_lqr_batch`, the doubling algorithm) instead of n scipy calls.
The coupled designs keep what they solved (`GainDesigner`): the next posture's problem starts
from the last Riccati solution (Newton-Hewer), on a chain basis rotated onto the last one.

The DOB's gain against this LQR ("paper-yield"). In the lab's accumulated reading of (25) the
static yield to a disturbance d is e = Ke^-1 Kdist d (`controller.composition`): Kdist means
something only together with the LQR's error gain per tick Ke. The paper's 0.2 and 1.0 were
chosen against its own design (diagonal Sm, Euler, Q = 10 I, R = I). `paper_yield_scale` gives,
per joint, Ke_ii of this design over Ke_ii of the paper's design on the same Sm: Kdist times it
yields as the paper's Kdist did against the paper's gain.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np
import scipy.linalg

from controller.closed_chain import (
    aligned_basis,
    chain_coordinates,
    gain_from_chain,
    motion_subspace,
)
from controller.lqr import (
    COUPLINGS,
    LQR_DESIGNS,
    Coupling,
    LqrDesign,
    LqrWeights,
    TrackingGain,
    design_on_model,
)
from controller.model import (
    FlexibleJointParams,
    StateSpace,
    flexible_joint_state_space,
    validate_sm,
)
from controller.riccati import discrete_lqr_batch
from controller.servo_cascade import (
    N_CASCADE_MOTOR_STATES,
    ServoCascadeParams,
    cascade_state_space,
)

ServoModel = Literal["first-order", "cascade"]
SERVO_MODELS: tuple[str, ...] = get_args(ServoModel)
KdistReference = Literal["per-tick", "paper-yield"]
KDIST_REFERENCES: tuple[str, ...] = get_args(KdistReference)


def _model(
    joints: FlexibleJointParams, sm: np.ndarray, servo: ServoCascadeParams | None
) -> tuple[StateSpace, int]:
    """The continuous model and its number of motor states per joint (1 or 2)."""
    if servo is None:
        return flexible_joint_state_space(joints, sm), 1
    return cascade_state_space(joints, servo, sm), N_CASCADE_MOTOR_STATES


def _tracking_gain(
    gain: np.ndarray, n: int, motor_states: int, dt_s: float, radius: float
) -> TrackingGain:
    """A gain on [e (n); motor states (motor_states n); d theta_j (n); d dtheta_j (n)] as a
    `TrackingGain` (the motor velocity's block, if any, apart)."""
    motor = gain[:, n : 2 * n]
    links = gain[:, n * (1 + motor_states) :]
    velocity = gain[:, 2 * n : 3 * n].copy() if motor_states == 2 else None
    return TrackingGain(
        error_gain=gain[:, :n].copy(),
        state_increment_gain=np.hstack([motor, links]),
        dt_s=float(dt_s),
        spectral_radius=radius,
        motor_velocity_increment_gain=velocity,
    )


def _sampled_batch(
    a: np.ndarray, b: np.ndarray, dt_s: float, method: str
) -> tuple[np.ndarray, np.ndarray]:
    """(B, s, s), (B, s, m) continuous models sampled at dt_s, Euler or ZOH (batched expm)."""
    if method == "euler":
        return np.eye(a.shape[-1]) + a * dt_s, b * dt_s
    s, m = b.shape[-2:]
    block = np.zeros((a.shape[0], s + m, s + m))
    block[:, :s, :s] = a
    block[:, :s, s:] = b
    exponential = scipy.linalg.expm(block * dt_s)
    return exponential[:, :s, :s], exponential[:, :s, s:]


def _design_diagonal(
    joints: FlexibleJointParams,
    sm: np.ndarray,
    dt_s: float,
    weights: LqrWeights,
    method: LqrDesign,
    servo: ServoCascadeParams | None,
) -> tuple[np.ndarray, float, int]:
    """n one-joint problems on Sm_ii, one batch; the gain placed block-diagonally."""
    n = joints.n_joints
    # Sm diagonal: the n-joint model is n one-joint models; gather each joint's block
    full, motor_states = _model(joints, np.diag(np.diag(sm)), servo)
    size = full.a.shape[0] // n
    index = np.arange(size)[None, :] * n + np.arange(n)[:, None]  # (n joints, size)
    a = full.a[index[:, :, None], index[:, None, :]]
    joint = np.arange(n)[:, None]
    b = full.b[index, joint][:, :, None]
    c = full.c[joint, index][:, None, :]
    q = np.diag(np.r_[weights.tracking_error_weight, np.full(size, weights.state_increment_weight)])
    q = np.broadcast_to(q, (n, size + 1, size + 1)).copy()
    r = np.full((n, 1, 1), weights.input_increment_weight)
    # augmented [e; dx]: (21) continuous for the sampled cost, the discrete form otherwise
    zeros_col = np.zeros((n, size, 1))
    if method == "continuous-cost":
        a_bar = np.block([[np.zeros((n, 1, 1)), c], [zeros_col, a]])
        b_bar = np.concatenate([np.zeros((n, 1, 1)), b], axis=1)
        phi, gamma, qd, cross, rd = _van_loan_batch(a_bar, b_bar, q, r, dt_s)
        solution = discrete_lqr_batch(phi, gamma, qd, rd, cross)
        gains = solution.gain.copy()
        gains[:, :, 0] *= dt_s  # w = duc/dt: duc(k) = -(K_e dt) e - K_x dx(k)
    else:
        a_d, b_d = _sampled_batch(a, b, dt_s, "euler" if method == "euler" else "zoh")
        a_aug = np.block([[np.ones((n, 1, 1)), c @ a_d], [zeros_col, a_d]])
        b_aug = np.concatenate([c @ b_d, b_d], axis=1)
        solution = discrete_lqr_batch(a_aug, b_aug, q, r)
        gains = solution.gain
    gain = np.zeros((n, n * (size + 1)))
    for block in range(size + 1):  # [e, motor states..., theta_j, dtheta_j] per joint
        gain[np.arange(n), block * n + np.arange(n)] = gains[:, 0, block]
    radius = float(np.max(np.abs(solution.closed_loop_eigenvalues)))
    return gain, radius, motor_states


def _van_loan_batch(
    a: np.ndarray, b: np.ndarray, q: np.ndarray, r: np.ndarray, dt_s: float
) -> tuple[np.ndarray, ...]:
    """`controller.lqr.sample_quadratic_cost` for a batch: phi, gamma, Qd, N, Rd."""
    batch, s, m = b.shape
    size = s + m
    f = np.zeros((batch, size, size))
    f[:, :s, :s] = a
    f[:, :s, s:] = b
    w = np.zeros((batch, size, size))
    w[:, :s, :s] = q
    w[:, s:, s:] = r
    big = np.zeros((batch, 2 * size, 2 * size))
    big[:, :size, :size] = -np.swapaxes(f, -1, -2)
    big[:, :size, size:] = w
    big[:, size:, size:] = f
    van_loan = scipy.linalg.expm(big * dt_s)
    transition = van_loan[:, size:, size:]
    weight = np.swapaxes(transition, -1, -2) @ van_loan[:, :size, size:]
    weight = 0.5 * (weight + np.swapaxes(weight, -1, -2))
    return (
        transition[:, :s, :s],
        transition[:, :s, s:],
        weight[:, :s, :s],
        weight[:, :s, s:],
        weight[:, s:, s:],
    )


@dataclass
class _WarmStart:
    """What the last coupled design of one structure left: its chain basis and Riccati solution."""

    basis: np.ndarray | None
    riccati: np.ndarray


class GainDesigner:
    """Designs for one controller's choices, remembering the last coupled solution per
    structure (the rank of Sm: double support 6, one foot 12) for a warm start. Deterministic:
    the same sequence of requests gives the same gains. `newton_steps` counts the warm steps.
    kdist_reference "paper-yield": each gain carries `paper_yield_scale` as its DOB scale."""

    def __init__(
        self,
        joints: FlexibleJointParams,
        dt_s: float,
        weights: LqrWeights,
        method: LqrDesign,
        coupling: Coupling,
        servo: ServoCascadeParams | None = None,
        kdist_reference: KdistReference = "per-tick",
    ) -> None:
        if method not in LQR_DESIGNS:
            raise ValueError(f"LQR design must be one of {LQR_DESIGNS}, got {method!r}")
        if coupling not in COUPLINGS:
            raise ValueError(f"coupling must be one of {COUPLINGS}, got {coupling!r}")
        if servo is not None and method == "euler":
            raise ValueError(
                "the servo cascade's fast pole (~ -(kv + b + D) / J) lies beyond forward "
                "Euler's limit -2/dt: design it with 'zoh' or 'continuous-cost'"
            )
        self.joints, self.dt_s, self.weights = joints, float(dt_s), weights
        self.method, self.coupling, self.servo = method, coupling, servo
        if kdist_reference not in KDIST_REFERENCES:
            raise ValueError(f"kdist_reference must be one of {KDIST_REFERENCES}")
        self.kdist_reference = kdist_reference
        self._warm: dict[int, _WarmStart] = {}
        self.newton_steps = 0

    def design(self, sm: np.ndarray) -> TrackingGain:
        """The gain for this Sm (validated by the caller: `controller.model.validate_sm`)."""
        gain = self._design(sm)
        if self.kdist_reference == "paper-yield":
            scale = paper_yield_scale(self.joints, sm, gain)
            gain = dataclasses.replace(gain, dob_gain_scale=scale)
        return gain

    def _design(self, sm: np.ndarray) -> TrackingGain:
        n = self.joints.n_joints
        if self.coupling == "diagonal":
            gain, radius, motor_states = _design_diagonal(
                self.joints, sm, self.dt_s, self.weights, self.method, self.servo
            )
            return _tracking_gain(gain, n, motor_states, self.dt_s, radius)
        full, motor_states = _model(self.joints, sm, self.servo)
        basis = None
        if self.coupling == "closed-chain":
            basis = motion_subspace(sm)
            if basis.shape[1] == n:
                basis = None  # nonsingular Sm: the chain's coordinates are the joints'
        key = n if basis is None else basis.shape[1]
        warm = self._warm.get(key)
        if basis is not None:
            basis = aligned_basis(basis, warm.basis if warm is not None else None)
            model = chain_coordinates(full, basis, motor_states * n)
        else:
            model = full
        result = design_on_model(
            model,
            self.dt_s,
            self.weights,
            self.method,
            start=None if warm is None else warm.riccati,
        )
        self.newton_steps += result.newton_steps
        self._warm[key] = _WarmStart(basis, result.riccati)
        gain = result.gain
        if basis is not None:
            gain = gain_from_chain(gain, basis, motor_states * n)
        return _tracking_gain(gain, n, motor_states, self.dt_s, result.spectral_radius)


def design_discrete_tracking_lqr(
    params: FlexibleJointParams,
    sm: np.ndarray,
    dt_s: float,
    weights: LqrWeights | None = None,
    method: LqrDesign = "zoh",
    coupling: Coupling = "full",
    servo: ServoCascadeParams | None = None,
) -> TrackingGain:
    """The gain the loop runs, designed from scratch (module docstring for the choices).

    method: "zoh" (default), "euler" (the lab's; refused with the cascade) or "continuous-cost".
    coupling: "full" (one problem on the whole Sm), "diagonal" (n one-joint problems on Sm's
    diagonal, the lab's; with a diagonal Sm both give the same gain) or "closed-chain".
    servo: None for the paper's first-order servo (4), else the cascade's figures.
    """
    weights = weights if weights is not None else LqrWeights()
    sm = validate_sm(sm, params.n_joints)
    return GainDesigner(params, dt_s, weights, method, coupling, servo).design(sm)


def paper_yield_scale(
    joints: FlexibleJointParams, sm: np.ndarray, gain: TrackingGain
) -> np.ndarray:
    """Per joint: this gain's Ke_ii over the paper's design's on the same Sm (diagonal, the
    paper's servo (4), Euler, Q = 10 I, R = I): Kdist times it yields as the paper's Kdist did
    (module docstring)."""
    reference = design_discrete_tracking_lqr(
        joints, np.diag(np.diag(sm)), gain.dt_s, LqrWeights(), "euler", "diagonal"
    )
    return np.diag(gain.error_gain) / np.diag(reference.error_gain)
