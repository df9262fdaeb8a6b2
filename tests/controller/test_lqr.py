"""LQR (21)-(24): Riccati residuals, closed-loop poles, the augmented model, argument checks."""

from __future__ import annotations

import numpy as np
import pytest

from controller.lqr import (
    LqrWeights,
    augmented_discrete,
    continuous_lqr,
    design_continuous_tracking_lqr,
    discrete_lqr,
)
from controller.lqr_designs import design_discrete_tracking_lqr
from controller.model import (
    FlexibleJointParams,
    discretise,
    flexible_joint_state_space,
    single_link_sm,
)

DT_S = 0.005
PAPER = FlexibleJointParams.uniform(1)


@pytest.mark.parametrize("inertia", [0.05, 0.25, 1.25, 2.0])
def test_continuous_design_is_hurwitz_with_zero_riccati_residual(inertia: float) -> None:
    sm = single_link_sm(inertia)
    solution = design_continuous_tracking_lqr(PAPER, sm, LqrWeights())
    system = flexible_joint_state_space(PAPER, sm)
    a = np.block([[np.zeros((1, 1)), system.c], [np.zeros((3, 1)), system.a]])  # (21)
    b = np.vstack([np.zeros((1, 1)), system.b])
    q = np.diag([10.0, 1.0, 1.0, 1.0])
    s = solution.riccati
    residual = a.T @ s + s @ a - s @ b @ b.T @ s + q  # (23) with R = 1
    assert np.max(np.abs(residual)) < 1e-8 * max(1.0, np.max(np.abs(s)))
    np.testing.assert_allclose(solution.gain, b.T @ s)  # (24)
    assert np.all(np.linalg.eigvals(a - b @ solution.gain).real < 0)
    # Integral action: the error weight alone fixes the error gain at sqrt(Qe / R).
    assert solution.gain[0, 0] == pytest.approx(np.sqrt(10.0), rel=1e-8)


def _riccati_by_iteration(a: np.ndarray, b: np.ndarray, q: np.ndarray, r: np.ndarray):
    """P of the DARE by value iteration, P <- Q + A'PA - A'PB (R + B'PB)^-1 B'PA (independent
    of scipy's solver)."""
    p = q.copy()
    for _ in range(100_000):
        p_next = q + a.T @ p @ a - a.T @ p @ b @ np.linalg.solve(r + b.T @ p @ b, b.T @ p @ a)
        if np.max(np.abs(p_next - p)) < 1e-13 * np.max(np.abs(p_next)):
            return p_next
        p = p_next
    raise AssertionError("the Riccati iteration did not converge")


@pytest.mark.parametrize("method", ["zoh", "euler"])
@pytest.mark.parametrize("inertia", [0.05, 0.25, 1.25])
def test_discrete_design_equals_an_independent_riccati_iteration(
    method: str, inertia: float
) -> None:
    """The product's gain against value iteration on the augmented model built here; plus the
    closed form of the error gain from the DARE's (1,1) block: Ke = sqrt(Qe / (R + B'PB))."""
    sm = single_link_sm(inertia)
    gain = design_discrete_tracking_lqr(PAPER, sm, DT_S, LqrWeights(), method)  # type: ignore[arg-type]
    sampled = discretise(flexible_joint_state_space(PAPER, sm), DT_S, method)  # type: ignore[arg-type]
    c = np.array([[0.0, 1.0, 0.0]])
    a = np.block([[np.eye(1), c @ sampled.a], [np.zeros((3, 1)), sampled.a]])
    b = np.vstack([c @ sampled.b, sampled.b])
    q, r = np.diag([10.0, 1.0, 1.0, 1.0]), np.eye(1)
    p = _riccati_by_iteration(a, b, q, r)
    expected = np.linalg.solve(r + b.T @ p @ b, b.T @ p @ a)
    np.testing.assert_allclose(gain.stacked, expected, rtol=1e-7, atol=1e-12)
    assert gain.error_gain[0, 0] == pytest.approx(np.sqrt(10.0 / (1.0 + b.T @ p @ b))[0, 0])
    radius = np.max(np.abs(np.linalg.eigvals(a - b @ expected)))
    assert radius < 1.0
    assert gain.spectral_radius == pytest.approx(radius, rel=1e-7)


def test_augmented_discrete_model_propagates_error_and_increments() -> None:
    """[e; dx](k+1) = A_aug [e; dx](k) + B_aug du(k) along any trajectory of the sampled plant."""
    params = FlexibleJointParams.uniform(2)
    sm = np.linalg.inv(np.array([[0.9, 0.25], [0.25, 0.15]]))
    plant = discretise(flexible_joint_state_space(params, sm), DT_S, "zoh")
    a_aug, b_aug = augmented_discrete(plant.a, plant.b, plant.c)
    rng = np.random.default_rng(3)
    reference = rng.normal(size=2)
    x_prev, u_prev = rng.normal(size=6), rng.normal(size=2)
    x = plant.a @ x_prev + plant.b @ u_prev
    for _ in range(20):
        u = u_prev + rng.normal(scale=0.1, size=2)
        x_next = plant.a @ x + plant.b @ u
        now = np.concatenate([plant.c @ x - reference, x - x_prev])
        after = np.concatenate([plant.c @ x_next - reference, x_next - x])
        np.testing.assert_allclose(after, a_aug @ now + b_aug @ (u - u_prev), atol=1e-9)
        x_prev, x, u_prev = x, x_next, u


def test_stacked_per_joint_design_equals_full_design_for_diagonal_sm() -> None:
    params = FlexibleJointParams(
        stiffness_nm_per_rad=[2000.0, 1500.0, 2500.0],
        damping_nms_per_rad=[100.0, 80.0, 120.0],
        servo_gain_per_s=[10.0, 18.0, 10.0],
    )
    sm = np.diag([4.0, 0.8, 20.0])
    full = design_discrete_tracking_lqr(params, sm, DT_S, coupling="full")
    stacked = design_discrete_tracking_lqr(params, sm, DT_S, coupling="diagonal")
    np.testing.assert_allclose(stacked.stacked, full.stacked, rtol=1e-8, atol=1e-12)
    # each per-joint block equals the 1-joint design
    one = design_discrete_tracking_lqr(params.joint(1), sm[1:2, 1:2], DT_S)
    np.testing.assert_allclose(full.stacked[1, [1, 4, 7, 10]], one.stacked[0], rtol=1e-8)
    # "diagonal" ignores the off-diagonal part of a coupled Sm, as the lab's code does
    coupled = sm + np.array([[0.0, 0.3, 0.0], [0.3, 0.0, 0.0], [0.0, 0.0, 0.0]])
    lab = design_discrete_tracking_lqr(params, coupled, DT_S, coupling="diagonal")
    np.testing.assert_allclose(lab.stacked, full.stacked, rtol=1e-8, atol=1e-12)


def test_lqr_argument_checks_name_the_problem() -> None:
    a, b = np.eye(2), np.ones((2, 1))
    q, r = np.eye(2), np.eye(1)
    with pytest.raises(ValueError, match="A must be square"):
        continuous_lqr(np.ones((2, 3)), b, q, r)
    with pytest.raises(ValueError, match="B must have 2 rows"):
        discrete_lqr(a, np.ones((3, 1)), q, r)
    with pytest.raises(ValueError, match="Q must be 2 x 2"):
        discrete_lqr(a, b, np.eye(3), r)
    with pytest.raises(ValueError, match="R must be positive definite"):
        discrete_lqr(a, b, q, np.zeros((1, 1)))
    with pytest.raises(ValueError, match="Q must be positive semi-definite"):
        continuous_lqr(a, b, -q, r)
    with pytest.raises(ValueError, match="symmetric"):
        continuous_lqr(a, b, np.array([[1.0, 1.0], [0.0, 1.0]]), r)
    with pytest.raises(ValueError, match="no stabilising"):
        continuous_lqr(np.eye(2), np.array([[1.0], [0.0]]), q, r)  # second mode uncontrollable
    with pytest.raises(ValueError, match="tracking_error_weight"):
        LqrWeights(tracking_error_weight=0.0)
    with pytest.raises(ValueError, match="input_increment_weight"):
        LqrWeights(input_increment_weight=-1.0)
    with pytest.raises(ValueError, match="coupling"):
        design_discrete_tracking_lqr(PAPER, np.eye(1), DT_S, coupling="block")  # type: ignore[arg-type]
