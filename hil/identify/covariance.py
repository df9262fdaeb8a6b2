"""Parameter covariance of a least-squares fit whose residuals are correlated in time.

For residuals r(p) (one row per sample, one column per output channel, already weighted) and
their Jacobian J = dr/dp at the optimum, the Gauss-Newton sandwich

    Cov(p) = H^-1 S H^-1,   H = sum_k J_k^T J_k,   S = long-run covariance of g_k = J_k^T r_k

is the covariance of the estimate when the residuals are noise. With white residuals S = s^2 H
and this is the textbook s^2 H^-1. The residuals of a simulated joint are not white (the sensor
quantisation is, but what the model misses is coloured), so S is the Newey-West estimate

    S = G_0 + sum_{l=1}^{L} (1 - l/(L+1)) (G_l + G_l^T),   G_l = sum_k g_k g_{k-l}^T

with the lag window L from Andrews' (1991) AR(1) plug-in rule, capped at N/4. Separate logs are
independent: their S add up.

Why not a bootstrap: an i.i.d. bootstrap assumes the white residuals this avoids; a block
bootstrap needs blocks longer than the residuals' correlation (seconds here) and a refit per
replicate (hundreds of fits of tens of seconds of data). The sandwich uses the one Jacobian the
fit already has. Neither covers a wrong model: the intervals are statistical, not a bound on
the bias of a model that differs from the joint (see the package docstring).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def andrews_lag_window(scores: np.ndarray) -> int:
    """Andrews' AR(1) plug-in lag window for the Bartlett kernel, per score column averaged.

    alpha = 4 rho^2 / ((1 - rho)^2 (1 + rho)^2),  L = 1.1447 (alpha N)^(1/3).
    """
    n = scores.shape[0]
    numerator = denominator = 0.0
    for column in scores.T:
        x0, x1 = column[:-1], column[1:]
        rho = float(np.dot(x0, x1) / max(np.dot(x0, x0), 1e-300))
        rho = min(max(rho, -0.99), 0.99)
        sigma2 = float(np.mean((x1 - rho * x0) ** 2))
        weight = sigma2**2 / max((1 - rho) ** 4, 1e-300)
        numerator += 4 * rho**2 * sigma2**2 / ((1 - rho) ** 6 * (1 + rho) ** 2)
        denominator += weight
    alpha = numerator / max(denominator, 1e-300)
    lag = 1.1447 * (alpha * n) ** (1.0 / 3.0)
    return int(min(max(lag, 1.0), n // 4))


def _long_run_covariance(scores: np.ndarray) -> np.ndarray:
    lag = andrews_lag_window(scores)
    s = scores.T @ scores
    for shift in range(1, lag + 1):
        gamma = scores[shift:].T @ scores[:-shift]
        s += (1.0 - shift / (lag + 1.0)) * (gamma + gamma.T)
    return s


def sandwich_covariance(
    jacobians: Sequence[np.ndarray], residuals: Sequence[np.ndarray]
) -> np.ndarray:
    """Cov(p) from per-log blocks: jacobians[i] (N_i, C, P), residuals[i] (N_i, C).

    Returns a (P, P) matrix (pseudo-inverse where H is singular: those directions get the
    variance the data cannot bound, which shows as huge entries).
    """
    p = jacobians[0].shape[2]
    hessian = np.zeros((p, p))
    meat = np.zeros((p, p))
    for jac, res in zip(jacobians, residuals, strict=True):
        hessian += np.einsum("kcp,kcq->pq", jac, jac)
        scores = np.einsum("kcp,kc->kp", jac, res)
        meat += _long_run_covariance(scores)
    bread = np.linalg.pinv(hessian)
    return bread @ meat @ bread
