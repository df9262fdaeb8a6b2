"""The least-squares fit every estimator uses: weighted residual blocks minimised with
`scipy.optimize.least_squares` in fit coordinates (logarithmic for positive figures), with
intervals from the Jacobian and the sandwich covariance (`covariance.py`).
"""

from __future__ import annotations

import enum
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.optimize
import scipy.stats

from hil.identify.covariance import sandwich_covariance


class Scale(enum.Enum):
    LOG = "log"  # a positive figure, fitted as its logarithm (intervals stay positive)
    LINEAR = "linear"


@dataclass(frozen=True)
class Coordinate:
    scale: Scale
    step: float  # central-difference step in fit coordinates
    lower: float = -math.inf  # bounds in natural units (LINEAR only)
    upper: float = math.inf


def _to_fit(values: np.ndarray, coords: Sequence[Coordinate]) -> np.ndarray:
    return np.array(
        [math.log(v) if c.scale is Scale.LOG else v for v, c in zip(values, coords, strict=True)]
    )


def _from_fit(x: np.ndarray, coords: Sequence[Coordinate]) -> np.ndarray:
    return np.array(
        [math.exp(v) if c.scale is Scale.LOG else v for v, c in zip(x, coords, strict=True)]
    )


@dataclass(frozen=True)
class FitOutcome:
    values: np.ndarray
    low: np.ndarray
    high: np.ndarray
    residuals: list[np.ndarray]


Blocks = Callable[[np.ndarray], list[np.ndarray]]


def least_squares(
    blocks: Blocks, initial: np.ndarray, coords: Sequence[Coordinate], confidence: float
) -> FitOutcome:
    """Minimise the sum of squares of all blocks (each (N_i, C)) over the parameters.

    Returns the optimum with intervals from the sandwich covariance (covariance.py) in the
    fit coordinates, mapped back to natural units.
    """
    lower = np.array([c.lower if c.scale is Scale.LINEAR else -np.inf for c in coords])
    upper = np.array([c.upper if c.scale is Scale.LINEAR else np.inf for c in coords])
    x0 = np.clip(_to_fit(np.asarray(initial, dtype=float), coords), lower, upper)

    def flat(x: np.ndarray) -> np.ndarray:
        return np.concatenate([b.ravel() for b in blocks(_from_fit(x, coords))])

    solution = scipy.optimize.least_squares(
        flat, x0, bounds=(lower, upper), x_scale="jac", method="trf", xtol=1e-10, ftol=1e-10
    )
    x = solution.x
    at_optimum = blocks(_from_fit(x, coords))
    jacobians = [np.empty((*b.shape, len(x))) for b in at_optimum]
    for j, coord in enumerate(coords):
        up, down = x.copy(), x.copy()
        up[j] = min(x[j] + coord.step, upper[j])
        down[j] = max(x[j] - coord.step, lower[j])
        plus, minus = blocks(_from_fit(up, coords)), blocks(_from_fit(down, coords))
        for jac, bp, bm in zip(jacobians, plus, minus, strict=True):
            jac[..., j] = (bp - bm) / (up[j] - down[j])
    covariance = sandwich_covariance(jacobians, at_optimum)
    z = scipy.stats.norm.ppf(0.5 + confidence / 2)
    half = z * np.sqrt(np.maximum(np.diag(covariance), 0.0))
    low = _from_fit(np.maximum(x - half, lower), coords)
    high = _from_fit(np.minimum(x + half, upper), coords)
    return FitOutcome(_from_fit(x, coords), low, high, at_optimum)
