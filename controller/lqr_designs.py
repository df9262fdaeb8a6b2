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

Four designs are named in docs/humanoid.md; all keep the paper's structure (the augmented
derivative form (21), the incremental input (24), Qe = 10 I on the error and Qx = I on the
increments, the DOB's composition (25) in the lab's accumulated reading):

    paper         one support foot's Sm (controller.humanoid.support), diagonal, the servo (4),
                  Euler, R = I: Kim et al. as published, the lab's code
    lab           both feet's Sm in double support, otherwise as "paper"
    closed-chain  both feet's whole Sm on the chain's motions, the servo (4), Euler, R = I
    ours          the closed chain on the servo cascade, sampled exactly ("zoh"), R = 1e5,
                  Kdist against the paper's design ("paper-yield")

How ours differs from the paper, and why (docs/studies/lqr_design measures each point on the
emulated robot linearised about its stand, sim_backend/humanoid/linear.py):
- The servo. (4) makes the motor a kinematic source; the H54 is a spring (Kpp kv = 785 N m/rad)
  and damper (kv) to its goal in series with the gear. On (4) the LQR's gains on the link
  increments are large (14.7 per rad on an ankle pitch); through the real cascade, once the
  gearbox friction slips, they make the loop unstable at the Nyquist frequency (|z| up to 5):
  the chatter the link-noise watch stops. Designed on the cascade, they are what the servo can
  follow. The cascade's fast pole is beyond Euler's reach at 200 Hz: sampled exactly.
- The chain. With two feet down Sm is singular; "closed-chain" (controller.closed_chain)
  integrates only the error the legs can remove (no Jordan blocks at z = 1, no goals ramping
  against the ground).
- R. What the rigid-contact model does not have bounds the loop's gain: the emulated soles'
  contact is soft (MuJoCo's solref of 20 ms: the standing robot rocks on them at 3.7-5.4 Hz,
  2500 N m/rad about the stance sole's roll axis on one foot, as soft as a gear), and the joint
  encoders do not see that rocking. With the paper's R = I (an integral gain of 40-400 1/s) the
  loop drives those modes unstable (2.7 Hz on the emulated robot); R = 1e5 keeps the loop's
  bandwidth under them (integral gain ~1 1/s in double support, ~2 on one foot), and every
  oscillatory mode inside the unit circle in each support state with the friction stuck and
  sliding. R = 1e4 is stable on two feet only.
- Kdist. In the accumulated reading the static yield is Ke^-1 Kdist d: against a gain 25-100
  times gentler than the paper's, the paper's Kdist would yield 25-100 times more (the robot
  sinks onto its servo lag). "paper-yield" scales Kdist by Ke_ours / Ke_paper per joint, so that
  the paper's 0.2 and 1.0 yield what they yielded against the paper's design.

Cost per design (measured side by side, `hil bench loop --robot dyros-jet`, docs/humanoid.md):
"diagonal" builds the n one-joint problems as stacked arrays and solves them in one batch
(`controller.riccati.discrete_lqr_batch`, the doubling algorithm) instead of n scipy calls; the
coupled designs (one problem of 30-60 states) by the same algorithm, a batch of one, which on
these sizes beats scipy's QZ solver several times over from scratch (so no warm start is kept:
each design depends on its Sm alone, the same in every run).

The DOB's gain against this LQR ("paper-yield"). In the lab's accumulated reading of (25) the
static yield to a disturbance d is e = Ke^-1 Kdist d (`controller.composition`): Kdist means
something only together with the LQR's error gain per tick Ke. The paper's 0.2 and 1.0 were
chosen against its own design (diagonal Sm, Euler, Q = 10 I, R = I). `paper_yield_scale` gives,
per joint, Ke_ii of this design over Ke_ii of the paper's design on the same Sm: Kdist times it
yields as the paper's Kdist did against the paper's gain.
"""

from __future__ import annotations

import dataclasses
import enum

import numpy as np
import scipy.linalg

from controller.closed_chain import chain_coordinates, gain_from_chain, motion_subspace
from controller.lqr import (
    COUPLINGS,
    LQR_DESIGNS,
    Coupling,
    LqrDesign,
    LqrWeights,
    TrackingGain,
    design_on_model,
    servo_discretisation,
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


class ServoModel(enum.StrEnum):
    """The LQR's model of the actuator: the paper's first-order (4), or the cascade."""

    FIRST_ORDER = "first-order"
    CASCADE = "cascade"


SERVO_MODELS: tuple[str, ...] = tuple(member.value for member in ServoModel)


class KdistReference(enum.StrEnum):
    """What Kdist is measured against (see GainDesigner)."""

    PER_TICK = "per-tick"
    PAPER_YIELD = "paper-yield"


KDIST_REFERENCES: tuple[str, ...] = tuple(member.value for member in KdistReference)


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
    if method == LqrDesign.EULER:
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
    if method == LqrDesign.CONTINUOUS_COST:
        a_bar = np.block([[np.zeros((n, 1, 1)), c], [zeros_col, a]])
        b_bar = np.concatenate([np.zeros((n, 1, 1)), b], axis=1)
        phi, gamma, qd, cross, rd = _van_loan_batch(a_bar, b_bar, q, r, dt_s)
        solution = discrete_lqr_batch(phi, gamma, qd, rd, cross)
        gains = solution.gain.copy()
        gains[:, :, 0] *= dt_s  # w = duc/dt: duc(k) = -(K_e dt) e - K_x dx(k)
    else:
        a_d, b_d = _sampled_batch(a, b, dt_s, servo_discretisation(method))
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


class GainDesigner:
    """Designs for one controller's choices (module docstring); each gain depends on its Sm
    alone. kdist_reference "paper-yield": each gain carries `paper_yield_scale` as its DOB
    scale."""

    def __init__(
        self,
        joints: FlexibleJointParams,
        dt_s: float,
        weights: LqrWeights,
        method: LqrDesign,
        coupling: Coupling,
        servo: ServoCascadeParams | None = None,
        kdist_reference: KdistReference = "per-tick",
        *,
        reference_solver: bool = False,
    ) -> None:
        if method not in LQR_DESIGNS:
            raise ValueError(f"LQR design must be one of {LQR_DESIGNS}, got {method!r}")
        if coupling not in COUPLINGS:
            raise ValueError(f"coupling must be one of {COUPLINGS}, got {coupling!r}")
        if servo is not None and method == LqrDesign.EULER:
            raise ValueError(
                "the servo cascade's fast pole (~ -(kv + b + D) / J) lies beyond forward "
                "Euler's limit -2/dt: design it with 'zoh' or 'continuous-cost'"
            )
        self.joints, self.dt_s, self.weights = joints, float(dt_s), weights
        self.method, self.coupling, self.servo = method, coupling, servo
        if kdist_reference not in KDIST_REFERENCES:
            raise ValueError(f"kdist_reference must be one of {KDIST_REFERENCES}")
        self.kdist_reference = kdist_reference
        self.reference_solver = reference_solver  # the coupled designs by scipy (benches, checks)

    def design(self, sm: np.ndarray) -> TrackingGain:
        """The gain for this Sm (validated by the caller: `controller.model.validate_sm`)."""
        gain = self._design(sm)
        if self.kdist_reference == KdistReference.PAPER_YIELD:
            scale = paper_yield_scale(self.joints, sm, gain)
            gain = dataclasses.replace(gain, dob_gain_scale=scale)
        return gain

    def _design(self, sm: np.ndarray) -> TrackingGain:
        n = self.joints.n_joints
        if self.coupling == Coupling.DIAGONAL:
            gain, radius, motor_states = _design_diagonal(
                self.joints, sm, self.dt_s, self.weights, self.method, self.servo
            )
            return _tracking_gain(gain, n, motor_states, self.dt_s, radius)
        full, motor_states = _model(self.joints, sm, self.servo)
        basis = motion_subspace(sm) if self.coupling == Coupling.CLOSED_CHAIN else None
        if basis is not None and basis.shape[1] == n:
            basis = None  # nonsingular Sm: the chain's coordinates are the joints'
        model = full if basis is None else chain_coordinates(full, basis, motor_states * n)
        result = design_on_model(
            model, self.dt_s, self.weights, self.method, reference_solver=self.reference_solver
        )
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
