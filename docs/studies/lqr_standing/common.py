"""Shared set-up for the study scripts: the controller's model at the walking-ready posture."""

import math
import numpy as np
from controller import (
    ControllerParams,
    FlexibleJointParams,
    LqrWeights,
    discretise,
    flexible_joint_state_space,
)
from controller.lqr_designs import design_discrete_tracking_lqr
from controller.humanoid import (
    LEG_JOINT_NAMES,
    ContactProjectedInertia,
    LegModel,
    SmCoupling,
    SupportState,
    WALKING_READY_LEG_ANGLES_RAD,
)
from hil.config import load_config, robot_description_text

DT = 0.005
cfg = load_config(robot="dyros-jet")
lm = LegModel(robot_description_text(cfg))
cpi = ContactProjectedInertia(lm)
POSTURE = np.array(WALKING_READY_LEG_ANGLES_RAD)
kp = np.full(12, 10.0)
kp[[3, 9]] = 18.0
PARAMS = FlexibleJointParams(np.full(12, 2000.0), np.full(12, 100.0), kp)
NAMES = [n for n in LEG_JOINT_NAMES]


def sm(support=SupportState.DOUBLE, coupling=SmCoupling.FULL, posture=POSTURE):
    return cpi.sm(posture, support, coupling)


def gain(sm_design, method="euler", coupling="diagonal"):
    return design_discrete_tracking_lqr(PARAMS, sm_design, DT, LqrWeights(), method, coupling)


class Loop:
    """Sampled loop (no DOB): true plant (20) with true_sm, ZOH at DT; controller as the product:
    dx from measured differences (velocity = backward difference), duc = -(Ke e + Kx dx),
    u = u_prev + duc.  z = [x (3n), previous measured (3n), u_prev (n)]."""

    def __init__(self, g, true_sm, true_params=PARAMS, zero_vel_inc=False, error_projector=None):
        n = 12
        self.n = n
        pl = discretise(flexible_joint_state_space(true_params, true_sm), DT, "zoh")
        self.phi, self.gamma = pl.a, pl.b
        self.ke, self.kx = g.error_gain, g.state_increment_gain
        self.zero = zero_vel_inc
        self.P = np.eye(n) if error_projector is None else error_projector

    def step(self, z):
        n = self.n
        x, prev, u_prev = z[: 3 * n], z[3 * n : 6 * n], z[6 * n : 7 * n]
        tm, tj = x[:n], x[n : 2 * n]
        v = (tj - prev[n : 2 * n]) / DT
        meas = np.concatenate([tm, tj, v])
        inc = meas - prev
        if self.zero:
            inc[2 * n :] = 0
        duc = -(self.ke @ (self.P @ tj) + self.kx @ inc)
        u = u_prev + duc
        return np.concatenate([self.phi @ x + self.gamma @ u, meas, u])

    def matrix(self):
        return np.array([self.step(c) for c in np.eye(7 * self.n)]).T


class DobLoop(Loop):
    """Loop + DOB (accumulated reading, Euler nominal servo, Q pole 0.7): z += [q_prev (n)]."""

    def __init__(self, g, true_sm, kdist, **kw):
        super().__init__(g, true_sm, **kw)
        self.kdist = kdist
        self.a = 1 - PARAMS.servo_gain_per_s * DT
        self.b = PARAMS.servo_gain_per_s * DT

    def step(self, z):
        n = self.n
        x, prev, u_prev, q_prev = z[: 3 * n], z[3 * n : 6 * n], z[6 * n : 7 * n], z[7 * n : 8 * n]
        tm, tj = x[:n], x[n : 2 * n]
        v = (tj - prev[n : 2 * n]) / DT
        meas = np.concatenate([tm, tj, v])
        inc = meas - prev
        if self.zero:
            inc[2 * n :] = 0
        duc = -(self.ke @ (self.P @ tj) + self.kx @ inc)
        raw = (tm - self.a * prev[:n]) / self.b - u_prev
        q = 0.7 * q_prev + 0.3 * raw
        u = u_prev + duc + self.kdist * q
        return np.concatenate([self.phi @ x + self.gamma @ u, meas, u, q])

    def matrix(self):
        return np.array([self.step(c) for c in np.eye(8 * self.n)]).T


def modes(A, k=4):
    ev = np.linalg.eigvals(A)
    ev = ev[np.abs(ev - 1) > 1e-4]  # drop the exact 1's (constrained, link cannot move)
    ev = ev[np.argsort(-np.abs(ev))]
    out = []
    for lam in ev[:k]:
        if lam.imag < -1e-12:
            continue
        out.append(f"|z|={abs(lam):.4f} {abs(np.angle(lam)) / (2 * np.pi * DT):5.2f}Hz")
    return "; ".join(out)


def true_servo_plant(true_sm, J=0.25, kv=78.5, Ti=15.0, visc=1.14, kpp=None, K=2000.0, D=100.0):
    """Continuous linear plant with the emulated H54 servo (sim_backend/servo.py figures):
    J dd th_m = kv (Kpp (u - th_m) - d th_m) + I_s - tau_j - visc d th_m,
    d I_s = (kv / Ti) (Kpp (u - th_m) - d th_m),  tau_j = K (th_m - th_j) + D (d th_m - d th_j),
    dd th_j = Sm tau_j.  State [th_m, dth_m, I_s, th_j, dth_j] (5n), ZOH-sampled at DT.
    Returns (Phi, Gamma, C_motor, C_link) on the sampled state."""
    import scipy.linalg

    n = 12
    I = np.eye(n)
    kpp = PARAMS.servo_gain_per_s if kpp is None else kpp
    Kp = np.diag(kpp)
    A = np.zeros((5 * n, 5 * n))
    B = np.zeros((5 * n, n))
    m, vm, s, j, vj = [slice(i * n, (i + 1) * n) for i in range(5)]
    A[m, vm] = I
    A[vm, m] = (-kv * Kp - K * I) / J
    A[vm, vm] = (-kv - D - visc) * I / J
    A[vm, s] = I / J
    A[vm, j] = K * I / J
    A[vm, vj] = D * I / J
    B[vm] = kv * Kp / J
    A[s, m] = -(kv / Ti) * Kp
    A[s, vm] = -(kv / Ti) * I
    B[s] = (kv / Ti) * Kp
    A[j, vj] = I
    A[vj, m] = true_sm * K
    A[vj, vm] = true_sm * D
    A[vj, j] = -true_sm * K
    A[vj, vj] = -true_sm * D
    M = np.zeros((6 * n, 6 * n))
    M[: 5 * n, : 5 * n] = A
    M[: 5 * n, 5 * n :] = B
    E = scipy.linalg.expm(M * DT)
    return E[: 5 * n, : 5 * n], E[: 5 * n, 5 * n :], np.eye(5 * n)[m], np.eye(5 * n)[j]


class TrueLoop:
    """Controller as Loop (no DOB) on the true-servo plant. z = [x (5n), prev meas (3n), u_prev (n)]"""

    def __init__(self, g, true_sm, kdist=None, **kw):
        self.phi, self.gamma, self.cm, self.cj = true_servo_plant(true_sm, **kw)
        self.ke, self.kx = g.error_gain, g.state_increment_gain
        self.n = 12
        self.kdist = kdist
        self.a = 1 - PARAMS.servo_gain_per_s * DT
        self.b = PARAMS.servo_gain_per_s * DT

    def step(self, z):
        n = self.n
        nx = 5 * n
        x, prev, u_prev = z[:nx], z[nx : nx + 3 * n], z[nx + 3 * n : nx + 4 * n]
        tm, tj = self.cm @ x, self.cj @ x
        v = (tj - prev[n : 2 * n]) / DT
        meas = np.concatenate([tm, tj, v])
        inc = meas - prev
        duc = -(self.ke @ tj + self.kx @ inc)
        u = u_prev + duc
        out = [self.phi @ x + self.gamma @ u, meas, u]
        if self.kdist is not None:
            q_prev = z[nx + 4 * n :]
            q = 0.7 * q_prev + 0.3 * ((tm - self.a * prev[:n]) / self.b - u_prev)
            u = u + self.kdist * q
            out = [self.phi @ x + self.gamma @ u, meas, u, q]
        return np.concatenate(out)

    def matrix(self):
        size = 5 * self.n + 4 * self.n + (self.n if self.kdist is not None else 0)
        return np.array([self.step(c) for c in np.eye(size)]).T


def modes2(A):
    ev = np.linalg.eigvals(A)
    ev = ev[np.abs(ev - 1) > 1e-6]
    f = np.abs(np.angle(ev)) / (2 * np.pi * DT)
    osc = ev[(f > 0.3) & (ev.imag > 0)]
    slow = ev[f <= 0.3]
    osc = osc[np.argsort(-np.abs(osc))][:2]
    slow = slow[np.argsort(-np.abs(slow))][:1]
    tau = -DT / np.log(np.abs(slow[0])) if len(slow) else float("nan")
    return (
        "osc: "
        + "; ".join(
            f"|z|={abs(l):.4f} at {abs(np.angle(l)) / (2 * np.pi * DT):.2f} Hz" for l in osc
        )
        + f" | slowest real {abs(slow[0]):.5f} (tau {tau:.2f} s)"
    )
