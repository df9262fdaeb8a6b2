"""The three LQR designs (controller/lqr.py): the sampled continuous cost (Van Loan) checked
against closed forms and quadrature, its gain against an independent Riccati iteration, its
convergence to the paper's continuous design as dt -> 0, and the per-tick designs' weights.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.integrate
import scipy.linalg

from controller import FlexibleJointParams, LqrWeights, single_link_sm
from controller.lqr import (
    augmented_continuous,
    design_continuous_tracking_lqr,
    sample_quadratic_cost,
)
from controller.lqr_designs import design_discrete_tracking_lqr
from controller.model import flexible_joint_state_space

PAPER = FlexibleJointParams.uniform(1)
SM = single_link_sm(0.376)
DT_S = 0.005


def test_van_loan_matches_the_scalar_closed_form() -> None:
    """x' = a x + b w, w held: x(t) = e^{at} x0 + (b/a)(e^{at} - 1) w, and int_0^h q x^2 + r w^2
    expands to Qd = q (e^{2ah} - 1)/(2a), N = q (b/a) [(e^{2ah} - 1)/(2a) - (e^{ah} - 1)/a],
    Rd = r h + q (b/a)^2 [(e^{2ah} - 1)/(2a) - 2 (e^{ah} - 1)/a + h]."""
    a, b, q, r, h = -3.0, 2.0, 5.0, 0.7, 0.1
    cost = sample_quadratic_cost(np.array([[a]]), np.array([[b]]), np.eye(1) * q, np.eye(1) * r, h)
    e1, e2 = math.expm1(a * h) / a, math.expm1(2 * a * h) / (2 * a)
    assert cost.phi[0, 0] == pytest.approx(math.exp(a * h), rel=1e-12)
    assert cost.gamma[0, 0] == pytest.approx(b * e1, rel=1e-12)
    assert cost.state_weight[0, 0] == pytest.approx(q * e2, rel=1e-10)
    assert cost.cross_weight[0, 0] == pytest.approx(q * (b / a) * (e2 - e1), rel=1e-10)
    assert cost.input_weight[0, 0] == pytest.approx(
        r * h + q * (b / a) ** 2 * (e2 - 2 * e1 + h), rel=1e-10
    )


def _augmented() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    system = flexible_joint_state_space(PAPER, SM)
    a_bar, b_bar = augmented_continuous(system.a, system.b, system.c)
    q, r = LqrWeights().matrices(1)
    return a_bar, b_bar, q, r


def _weight_by_quadrature(dt: float) -> np.ndarray:
    """W with int_0^dt xi' Q xi + w' R w = z' W z (z = [xi(0); w]), by Simpson's rule on 4000
    intervals: the state matrix S(t) = expm(F t) is propagated step by step with the exact
    one-step map expm(F dt / 4000), and the integrand is S(t)' blockdiag(Q, R) S(t)."""
    a_bar, b_bar, q, r = _augmented()
    n = a_bar.shape[0]
    f = np.zeros((n + 1, n + 1))
    f[:n, :n], f[:n, n:] = a_bar, b_bar
    weight = scipy.linalg.block_diag(q, r)
    intervals = 4000
    step = scipy.linalg.expm(f * dt / intervals)
    state = np.eye(n + 1)
    integrand = np.empty((intervals + 1, n + 1, n + 1))
    for k in range(intervals + 1):
        integrand[k] = state.T @ weight @ state
        state = step @ state
    return scipy.integrate.simpson(integrand, dx=dt / intervals, axis=0)


def test_sampled_cost_of_the_augmented_testbed_equals_quadrature() -> None:
    a_bar, b_bar, q, r = _augmented()
    cost = sample_quadratic_cost(a_bar, b_bar, q, r, DT_S)
    quadrature = _weight_by_quadrature(DT_S)
    rng = np.random.default_rng(5)
    for _ in range(5):
        z = rng.normal(size=5) * np.array([0.01, 0.1, 0.1, 0.1, 0.5])
        xi, w = z[:4], z[4:]
        quadratic = (
            xi @ cost.state_weight @ xi + 2 * xi @ cost.cross_weight @ w + w @ cost.input_weight @ w
        )
        assert quadratic == pytest.approx(z @ quadrature @ z, rel=1e-6)


def test_continuous_cost_gain_equals_an_independent_riccati_iteration() -> None:
    """Weights by quadrature (above), plant by expm, and the DARE with cross term solved by
    value iteration: P <- Qd + Phi'P Phi - (Phi'P Gamma + N)(Rd + Gamma'P Gamma)^-1 (...)'."""
    a_bar, b_bar, _, _ = _augmented()
    n = 4
    weight = _weight_by_quadrature(DT_S)
    f = np.zeros((n + 1, n + 1))
    f[:n, :n], f[:n, n:] = a_bar, b_bar
    transition = scipy.linalg.expm(f * DT_S)
    phi, gamma = transition[:n, :n], transition[:n, n:]
    qd, nd, rd = weight[:n, :n], weight[:n, n:], weight[n:, n:]
    p = qd.copy()
    for _ in range(200_000):
        coupling = gamma.T @ p @ phi + nd.T
        p_next = (
            qd + phi.T @ p @ phi - coupling.T @ np.linalg.solve(rd + gamma.T @ p @ gamma, coupling)
        )
        done = np.max(np.abs(p_next - p)) < 1e-13 * np.max(np.abs(p))
        p = p_next
        if done:
            break
    gain = np.linalg.solve(rd + gamma.T @ p @ gamma, gamma.T @ p @ phi + nd.T)[0]
    product = design_discrete_tracking_lqr(PAPER, SM, DT_S, LqrWeights(), "continuous-cost")
    np.testing.assert_allclose(product.error_gain[0, 0], gain[0] * DT_S, rtol=1e-5)
    np.testing.assert_allclose(product.state_increment_gain[0], gain[1:], rtol=1e-5)
    # the figures the docstring of controller/lqr.py gives
    assert product.error_gain[0, 0] == pytest.approx(0.00258, abs=1e-5)
    assert product.integral_gain_per_s[0, 0] == pytest.approx(0.516, abs=1e-3)
    np.testing.assert_allclose(product.state_increment_gain[0], [0.945, -1.444, 0.0635], atol=1e-3)
    assert product.spectral_radius == pytest.approx(0.99242, abs=1e-5)
    assert product.dominant_time_constant_s == pytest.approx(0.657, abs=1e-3)


def test_continuous_cost_design_converges_to_the_papers_continuous_design() -> None:
    """As dt -> 0 the sampled problem is (22): the dominant pole ln(z)/dt tends to the
    continuous design's, and the error gain per second to sqrt(Qe/R) = sqrt(10) (the (1,1)
    block of (23): Ke' R Ke = Qe). The error gain converges slowly: the continuous optimum uses
    a -2,671 rad/s pole that only dt << 0.4 ms resolves."""
    continuous = design_continuous_tracking_lqr(PAPER, SM, LqrWeights())
    poles = continuous.closed_loop_eigenvalues
    dominant = poles[np.argmax(poles.real)]
    assert continuous.gain[0, 0] == pytest.approx(math.sqrt(10.0), rel=1e-9)
    assert dominant.real == pytest.approx(-1.5222, abs=1e-4)
    assert abs(dominant.imag) == pytest.approx(0.9115, abs=1e-4)
    gain_errors, pole_errors = [], []
    for dt in (5e-3, 1e-3, 2e-4, 5e-5):
        sampled = design_discrete_tracking_lqr(PAPER, SM, dt, LqrWeights(), "continuous-cost")
        gain = np.concatenate([sampled.integral_gain_per_s[0], sampled.state_increment_gain[0]])
        gain_errors.append(np.linalg.norm(gain - continuous.gain[0]))
        assert sampled.dominant_time_constant_s == pytest.approx(-1 / dominant.real, rel=1e-3)
        pole_errors.append(abs(sampled.dominant_time_constant_s + 1 / dominant.real))
    assert all(
        later < earlier for earlier, later in zip(gain_errors, gain_errors[1:], strict=False)
    )
    assert gain_errors[-2] / gain_errors[-1] > 2.5  # ~first order in dt once dt << 0.4 ms
    assert gain_errors[-1] < 0.08 * np.linalg.norm(continuous.gain[0])
    assert gain_errors[0] > 0.5 * np.linalg.norm(continuous.gain[0])  # far from it at 200 Hz


@pytest.mark.parametrize("method", ["euler", "zoh"])
def test_per_tick_designs_weigh_the_error_1_over_dt_squared_more_than_22(method: str) -> None:
    """Summed over ticks, (22) is (1/dt) sum (Qe dt^2 e^2 + Qx dx^2 + R du^2): the per-tick
    design with Qe scaled by dt^2 is (22)'s sampled problem to first order (a rectangle rule):
    its dominant mode is the continuous design's 0.657 s and its error gain is of the order of
    the exactly sampled cost's (within 2.5x), while the lab's Qe = 10 gives 84x more."""
    lab = design_discrete_tracking_lqr(PAPER, SM, DT_S, LqrWeights(), method)  # type: ignore[arg-type]
    consistent = design_discrete_tracking_lqr(
        PAPER,
        SM,
        DT_S,
        LqrWeights(10.0 * DT_S**2, 1.0, 1.0),
        method,  # type: ignore[arg-type]
    )
    sampled_cost = design_discrete_tracking_lqr(PAPER, SM, DT_S, LqrWeights(), "continuous-cost")
    assert lab.error_gain[0, 0] / sampled_cost.error_gain[0, 0] > 50
    ratio = consistent.error_gain[0, 0] / sampled_cost.error_gain[0, 0]
    assert 0.4 < ratio < 2.5
    assert consistent.dominant_time_constant_s == pytest.approx(0.657, rel=0.01)
    assert lab.integral_gain_per_s[0, 0] == pytest.approx(
        {"euler": 43.39, "zoh": 77.31}[method], abs=0.01
    )
