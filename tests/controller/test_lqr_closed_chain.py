"""The closed-chain LQR design (controller.lqr, coupling "closed-chain"), checked against
closed forms and against the loop written out from the equations.

A two-joint chain with Sm = lam v v', v = (1, 1)/sqrt 2 (two joints that can only move
together, as two legs on the ground): in the coordinates s = v'(.) and a = w'(.),
w = (1, -1)/sqrt 2, the model (20) splits into one flexible joint with Sm = lam on s and a bare
servo on the motors' difference a (no link motion). The cost is invariant under that rotation,
so the optimal gain is the 1-joint design on s plus the servo-only scalar DARE on a:
    du = -(ke v v' e + (km v v' + ka w w') d theta_m + kj v v' d theta_j + kv v v' d dtheta_j).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from controller import FlexibleJointParams, LqrWeights, design_discrete_tracking_lqr, discretise
from controller.closed_chain import motion_subspace
from controller.model import flexible_joint_state_space, single_link_sm

DT_S = 0.005
LAM = 1.0 / 0.376  # the testbed link's inverse inertia
V = np.array([1.0, 1.0]) / math.sqrt(2.0)
W = np.array([1.0, -1.0]) / math.sqrt(2.0)
URDF = Path(__file__).resolve().parents[2] / "hil" / "data" / "robots" / "dyros_jet.urdf"


def _servo_only_gain(method: str, kp: float = 10.0) -> tuple[float, float]:
    """Scalar DARE for dm(k+1) = a dm(k) + b du(k), Q = 1, R = 1 (fixed-point iteration):
    the gain and the closed-loop pole a - b k."""
    a, b = (1 - kp * DT_S, kp * DT_S) if method == "euler" else (math.exp(-kp * DT_S), 0.0)
    if method != "euler":
        b = 1 - a
    p = 1.0
    for _ in range(10_000):
        p = a * a * p - (a * b * p) ** 2 / (1 + b * b * p) + 1.0
    k = a * b * p / (1 + b * b * p)
    return k, a - b * k


@pytest.mark.parametrize("method", ["euler", "zoh"])
def test_rank_one_chain_is_one_joint_plus_a_bare_servo(method: str) -> None:
    params = FlexibleJointParams.uniform(2)
    gain = design_discrete_tracking_lqr(
        params, LAM * np.outer(V, V), DT_S, LqrWeights(), method, "closed-chain"
    )
    one = design_discrete_tracking_lqr(
        FlexibleJointParams.uniform(1), single_link_sm(0.376), DT_S, LqrWeights(), method
    )
    ke, km, kj, kv = one.error_gain[0, 0], *one.state_increment_gain[0]
    ka, servo_pole = _servo_only_gain(method)
    vv, ww = np.outer(V, V), np.outer(W, W)
    assert np.allclose(gain.error_gain, ke * vv, atol=1e-9)
    assert np.allclose(gain.state_increment_gain[:, :2], km * vv + ka * ww, atol=1e-9)
    assert np.allclose(gain.state_increment_gain[:, 2:4], kj * vv, atol=1e-9)
    assert np.allclose(gain.state_increment_gain[:, 4:], kv * vv, atol=1e-9)
    # the designed loop's slowest pole: the joint's or the bare servo's (it is the servo's)
    assert gain.spectral_radius == pytest.approx(max(one.spectral_radius, servo_pole), abs=1e-9)


def test_nonsingular_sm_gives_the_full_design() -> None:
    params = FlexibleJointParams.uniform(2)
    sm = np.linalg.inv(np.array([[0.9, 0.25], [0.25, 0.15]]))
    full = design_discrete_tracking_lqr(params, sm, DT_S, LqrWeights(), "zoh", "full")
    chain = design_discrete_tracking_lqr(params, sm, DT_S, LqrWeights(), "zoh", "closed-chain")
    assert np.allclose(full.stacked, chain.stacked, atol=1e-9)


def test_motion_subspace_is_the_range_of_sm() -> None:
    basis = motion_subspace(LAM * np.outer(V, V))
    assert basis.shape == (2, 1) and abs(abs(basis[:, 0] @ V) - 1.0) < 1e-12
    with pytest.raises(ValueError):
        motion_subspace(np.diag([1.0, -1.0]))


def _goal_after(gain, sm: np.ndarray, error_rad: np.ndarray, ticks: int) -> np.ndarray:
    """The sampled loop (nominal servo, exact ZOH plant) with a constant reference offset
    `error_rad` (link at 0, reference at -error): duc = -(Ke e + Kx dx), u = u + duc."""
    params = FlexibleJointParams.uniform(2)
    plant = discretise(flexible_joint_state_space(params, sm), DT_S, "zoh")
    x = np.zeros(6)
    previous = np.zeros(6)
    u = np.zeros(2)
    for _ in range(ticks):
        measured = np.concatenate([x[:2], x[2:4], (x[2:4] - previous[2:4]) / DT_S])
        u = u - (
            gain.error_gain @ (x[2:4] + error_rad)
            + gain.state_increment_gain @ (measured - previous)
        )
        previous = measured
        x = plant.a @ x + plant.b @ u
    return u


def test_per_joint_integrators_wind_up_on_an_error_the_chain_cannot_remove() -> None:
    """A reference 1 mrad apart along w (which the chain cannot move): the diagonal design's
    goal ramps along w at ke e / (1 + km) per tick (steady ramp: d theta_m = du, link still),
    the closed-chain design's goal settles."""
    sm = LAM * np.outer(V, V)
    params = FlexibleJointParams.uniform(2)
    error = 1e-3 * W
    diagonal = design_discrete_tracking_lqr(params, sm, DT_S, LqrWeights(), "euler", "diagonal")
    chain = design_discrete_tracking_lqr(params, sm, DT_S, LqrWeights(), "euler", "closed-chain")
    ke, km = diagonal.error_gain[0, 0], diagonal.state_increment_gain[0, 0]
    rate = W @ (_goal_after(diagonal, sm, error, 2001) - _goal_after(diagonal, sm, error, 2000))
    assert rate == pytest.approx(-ke * 1e-3 / (1 + km), rel=1e-6)
    settled = _goal_after(chain, sm, error, 2000)
    assert np.allclose(settled, _goal_after(chain, sm, error, 2001), atol=1e-12)


@pytest.fixture(scope="module")
def double_support_sm() -> np.ndarray:
    from controller.humanoid import (
        WALKING_READY_LEG_ANGLES_RAD,
        ContactProjectedInertia,
        LegModel,
        SupportState,
    )

    model = LegModel(URDF.read_text())
    return ContactProjectedInertia(model).sm(
        np.array(WALKING_READY_LEG_ANGLES_RAD), SupportState.DOUBLE
    )


def _humanoid_params() -> FlexibleJointParams:
    kp = np.full(12, 10.0)
    kp[[3, 9]] = 18.0  # the lab's knees
    return FlexibleJointParams(np.full(12, 2000.0), np.full(12, 100.0), kp)


def _loop_radius(gain, sm: np.ndarray) -> float:
    """Spectral radius of the sampled loop on the coupled plant, leaving out the eigenvalues at
    exactly 1 of the link's constrained directions (they have no dynamics: Sm tau = 0 there)."""
    params = _humanoid_params()
    plant = discretise(flexible_joint_state_space(params, sm), DT_S, "zoh")
    n = 12

    def step(z: np.ndarray) -> np.ndarray:
        x, previous, u = z[: 3 * n], z[3 * n : 6 * n], z[6 * n :]
        link = x[n : 2 * n]
        measured = np.concatenate([x[:n], link, (link - previous[n : 2 * n]) / DT_S])
        u = u - (gain.error_gain @ link + gain.state_increment_gain @ (measured - previous))
        return np.concatenate([plant.a @ x + plant.b @ u, measured, u])

    matrix = np.array([step(column) for column in np.eye(7 * n)]).T
    eigenvalues = np.linalg.eigvals(matrix)
    return float(np.max(np.abs(eigenvalues[np.abs(eigenvalues - 1) > 1e-4])))


def test_double_support_designs_on_the_coupled_plant(double_support_sm: np.ndarray) -> None:
    """DYROS-JET standing on two feet (walking-ready posture): Sm has rank 6 (18 - 12
    constraints); "full" has no stabilising DARE (6 error integrators no input reaches); the
    lab's per-joint design is unstable on the coupled plant (a 3.4 Hz sagittal mode); the
    closed-chain design runs as designed."""
    sm = double_support_sm
    assert np.linalg.matrix_rank(sm, tol=1e-8 * np.abs(sm).max()) == 6
    params = _humanoid_params()
    with pytest.raises(ValueError, match="no stabilising"):
        design_discrete_tracking_lqr(params, sm, DT_S, LqrWeights(), "euler", "full")
    diagonal = design_discrete_tracking_lqr(
        params, np.diag(np.diag(sm)), DT_S, LqrWeights(), "euler", "diagonal"
    )
    chain = design_discrete_tracking_lqr(params, sm, DT_S, LqrWeights(), "euler", "closed-chain")
    assert _loop_radius(diagonal, sm) > 1.003
    assert _loop_radius(chain, sm) == pytest.approx(chain.spectral_radius, abs=2e-3)
    assert chain.spectral_radius < 0.94
    # no integral action on what the chain cannot move
    null = np.linalg.eigh(sm)[1][:, :6]
    assert np.abs(chain.error_gain @ null).max() < 1e-9


def test_the_cascade_on_the_closed_chain(double_support_sm: np.ndarray) -> None:
    """The closed chain with the servo cascade: no error gain (nor link gain) in Sm's null space;
    the doubling solver gives scipy's gain; a design depends on its Sm alone."""
    from controller import GainDesigner, ServoCascadeParams

    sm = double_support_sm
    params = _humanoid_params()
    servo = ServoCascadeParams.h54(12)
    weights = LqrWeights(input_increment_weight=1e5)
    gain = design_discrete_tracking_lqr(params, sm, DT_S, weights, "zoh", "closed-chain", servo)
    null = np.linalg.eigh(sm)[1][:, :6]
    assert np.abs(gain.error_gain @ null).max() < 1e-9
    assert np.abs(gain.state_increment_gain[:, 12:] @ np.kron(np.eye(2), null)).max() < 1e-9
    assert gain.motor_velocity_increment_gain is not None
    assert gain.spectral_radius < 1
    reference = GainDesigner(
        params, DT_S, weights, "zoh", "closed-chain", servo, reference_solver=True
    ).design(sm)
    assert np.allclose(gain.stacked, reference.stacked, rtol=1e-8, atol=1e-12)
    # the design depends on its Sm alone: a designer that designed another posture first
    # gives the same gain as one that did not
    from controller.humanoid import (
        WALKING_READY_LEG_ANGLES_RAD,
        ContactProjectedInertia,
        LegModel,
        SupportState,
    )

    posture = np.array(WALKING_READY_LEG_ANGLES_RAD) + 0.002  # 2 mrad on every joint
    nearby = ContactProjectedInertia(LegModel(URDF.read_text())).sm(posture, SupportState.DOUBLE)
    designer = GainDesigner(params, DT_S, weights, "zoh", "closed-chain", servo)
    designer.design(sm)
    again = designer.design(nearby)
    fresh = design_discrete_tracking_lqr(
        params, nearby, DT_S, weights, "zoh", "closed-chain", servo
    )
    assert np.array_equal(again.stacked, fresh.stacked)
