"""The Riccati solvers of controller/riccati.py against scipy.linalg.solve_discrete_are, and the
batched diagonal design against the one-joint designs it replaces."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from controller import FlexibleJointParams, LqrWeights, ServoCascadeParams
from controller.lqr_designs import design_discrete_tracking_lqr
from controller.riccati import discrete_lqr_batch

DT_S = 0.005


def _residual(a, b, q, r, p, n=None) -> float:
    """The DARE's residual relative to P."""
    coupling = b.T @ p @ a + (0 if n is None else n.T)
    lhs = a.T @ p @ a - p - coupling.T @ np.linalg.solve(r + b.T @ p @ b, coupling) + q
    return float(np.max(np.abs(lhs)) / max(1.0, np.max(np.abs(p))))


def _random_problems(seed: int, batch: int, n: int, m: int):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(batch, n, n))
    a *= 1.3 / np.max(np.abs(np.linalg.eigvals(a)), axis=1)[:, None, None]  # some unstable
    b = rng.normal(size=(batch, n, m))
    c = rng.normal(size=(batch, n, n))
    q = c @ np.swapaxes(c, -1, -2) + 0.1 * np.eye(n)
    d = rng.normal(size=(batch, m, m))
    r = d @ np.swapaxes(d, -1, -2) + np.eye(m)
    return a, b, q, r


@pytest.mark.parametrize(("n", "m"), [(4, 1), (5, 2), (8, 3)])
def test_the_batched_solver_agrees_with_scipy(n: int, m: int) -> None:
    a, b, q, r = _random_problems(n * 10 + m, 12, n, m)
    solution = discrete_lqr_batch(a, b, q, r)
    for k in range(12):
        reference = scipy.linalg.solve_discrete_are(a[k], b[k], q[k], r[k])
        assert np.allclose(solution.riccati[k], reference, rtol=1e-9, atol=1e-9)
        assert _residual(a[k], b[k], q[k], r[k], solution.riccati[k]) < 1e-9
        gain = np.linalg.solve(r[k] + b[k].T @ reference @ b[k], b[k].T @ reference @ a[k])
        assert np.allclose(solution.gain[k], gain, rtol=1e-8, atol=1e-9)
    assert np.all(np.max(np.abs(solution.closed_loop_eigenvalues), axis=1) < 1)


def test_the_batched_solver_with_a_cross_weight_agrees_with_scipy() -> None:
    a, b, q, r = _random_problems(7, 6, 4, 1)
    rng = np.random.default_rng(8)
    cross = 0.1 * rng.normal(size=(6, 4, 1))
    solution = discrete_lqr_batch(a, b, q, r, cross)
    for k in range(6):
        reference = scipy.linalg.solve_discrete_are(a[k], b[k], q[k], r[k], s=cross[k])
        assert np.allclose(solution.riccati[k], reference, rtol=1e-9, atol=1e-9)
        assert _residual(a[k], b[k], q[k], r[k], solution.riccati[k], cross[k]) < 1e-9


def test_the_batched_solver_refuses_an_unstabilisable_problem() -> None:
    a = np.array([[[1.2, 0.0], [0.0, 0.5]]])  # the unstable state is not reached by the input
    b = np.array([[[0.0], [1.0]]])
    with pytest.raises(ValueError, match="stabilising"):
        discrete_lqr_batch(a, b, np.eye(2)[None], np.eye(1)[None])


def test_the_doubling_solver_on_a_coupled_problem_agrees_with_scipy() -> None:
    """One larger problem (a batch of one), as the coupled designs use it."""
    a, b, q, r = _random_problems(3, 1, 30, 6)
    solution = discrete_lqr_batch(a, b, q, r)
    reference = scipy.linalg.solve_discrete_are(a[0], b[0], q[0], r[0])
    assert np.allclose(solution.riccati[0], reference, rtol=1e-9, atol=1e-9)
    assert _residual(a[0], b[0], q[0], r[0], solution.riccati[0]) < 1e-9


@pytest.mark.parametrize("method", ["euler", "zoh", "continuous-cost"])
def test_the_diagonal_design_is_the_one_joint_designs_stacked(method: str) -> None:
    """The lab's design solved as one batch equals n one-joint designs (each by scipy)."""
    rng = np.random.default_rng(1)
    n = 12
    params = FlexibleJointParams(
        np.full(n, 2000.0), np.full(n, 100.0), np.where(np.arange(n) % 6 == 3, 18.0, 10.0)
    )
    sm = np.diag(rng.uniform(0.1, 3.0, n))  # inertias 0.33-10 kg m^2: Euler keeps them stable
    batched = design_discrete_tracking_lqr(params, sm, DT_S, LqrWeights(), method, "diagonal")
    for joint in range(n):
        one = design_discrete_tracking_lqr(
            params.joint(joint), sm[joint : joint + 1, joint : joint + 1], DT_S, method=method
        )
        assert batched.error_gain[joint, joint] == pytest.approx(one.error_gain[0, 0], rel=1e-9)
        for block in range(3):
            assert batched.state_increment_gain[joint, block * n + joint] == pytest.approx(
                one.state_increment_gain[0, block], rel=1e-8, abs=1e-12
            )
    off_diagonal = batched.error_gain - np.diag(np.diag(batched.error_gain))
    assert not off_diagonal.any()


def test_the_diagonal_cascade_design_is_the_one_joint_cascade_designs_stacked() -> None:
    n = 4
    params = FlexibleJointParams.uniform(n)
    servo = ServoCascadeParams.h54(n)
    sm = np.diag([0.4, 1.0, 2.5, 8.0])
    batched = design_discrete_tracking_lqr(
        params, sm, DT_S, method="zoh", coupling="diagonal", servo=servo
    )
    for joint in range(n):
        one = design_discrete_tracking_lqr(
            params.joint(joint),
            sm[joint : joint + 1, joint : joint + 1],
            DT_S,
            servo=servo.joint(joint),
        )
        assert batched.motor_velocity_increment_gain is not None
        assert batched.motor_velocity_increment_gain[joint, joint] == pytest.approx(
            one.motor_velocity_increment_gain[0, 0], rel=1e-8
        )
        assert batched.error_gain[joint, joint] == pytest.approx(one.error_gain[0, 0], rel=1e-8)
