"""What an impact run's "steady state" is: the quasi-static error after the push, and the
equilibrium estimated from the slow mode. Pure numpy/scipy on a run's time, link and reference.

Why two figures (the derivation is in docs/reproduction.md, "steady-state error"). With the
DOB in the lab's accumulated reading of (25), the link rests where the LQR's integral balances
the DOB: Ke e = Kdist q, and the DOB senses a load tau only through the servo's position lag,
q ~ -(tau - I_s) / k_s. The servo's velocity-loop integral I_s winds that lag out with its
integral time Ti_s, so after the fast transients the error relaxes as

    e(t) = e_eq + (e(t0) - e_eq) exp(-(t - t0) / tau_slow),   tau_slow = Ti_s,  e_eq = 0

(tau_slow = Ti_s exactly in the quasi-static limit when the nominal Kp equals the servo's Kpp;
15 s on the emulated H54). A 5 s run ends 4 s after the push, inside that mode: its final error
is the quasi-static error at that time, not an equilibrium. So a report gives
- `quasi_static_error`: the error (link - reference) averaged over a short window at a stated
  time after the push, named with that time;
- `fit_slow_mode`: e_eq, tau_slow and their standard errors from an exponential fit over a long
  enough record, or a `SlowModeFitError` saying why the record cannot tell (too short for the
  time constant, no decay above the noise, the time constant at the edge of the search).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

DEFAULT_WINDOW_S = 0.1
MIN_TIME_CONSTANT_S = 0.05
MAX_TIME_CONSTANT_S = 1000.0
MIN_RECORD_TIME_CONSTANTS = 1.0  # the record must span at least this many time constants
MAX_RELATIVE_STD = 0.2  # of the time constant, and of the equilibrium against the amplitude
MIN_AMPLITUDE_NOISE_RATIO = 5.0


class SlowModeFitError(ValueError):
    """The record does not determine the slow mode (the message says why)."""


@dataclass(frozen=True)
class QuasiStaticError:
    """Mean link error (link - reference) [rad] over `window_s` centred `after_push_s` after the
    push started: the quasi-static error at that time, not an equilibrium."""

    after_push_s: float
    window_s: float
    error_rad: float


@dataclass(frozen=True)
class SlowModeFit:
    """e(t) = equilibrium_error_rad + amplitude_rad exp(-(t - start_s) / time_constant_s),
    fitted over [start_s, end_s]; *_std: standard errors from the fit's covariance (noise only,
    not model error); residual_rms_rad: rms of the data about the fit."""

    equilibrium_error_rad: float
    time_constant_s: float
    amplitude_rad: float
    start_s: float
    end_s: float
    equilibrium_std_rad: float
    time_constant_std_s: float
    residual_rms_rad: float

    def value_at(self, time_s: np.ndarray | float) -> np.ndarray:
        t = np.asarray(time_s, dtype=float)
        return self.equilibrium_error_rad + self.amplitude_rad * np.exp(
            -(t - self.start_s) / self.time_constant_s
        )


def _error_signal(
    time_s: np.ndarray, link_rad: np.ndarray, reference_rad: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    time = np.asarray(time_s, dtype=float)
    link = np.asarray(link_rad, dtype=float)
    reference = np.asarray(reference_rad, dtype=float)
    if time.ndim != 1 or link.shape != time.shape or reference.shape != time.shape:
        raise ValueError(
            f"time, link and reference must be 1-D arrays of one length, got {time.shape}, "
            f"{link.shape}, {reference.shape}"
        )
    error = link - reference
    if time.size > 1 and np.any(np.diff(time) <= 0):
        raise ValueError("time must increase strictly")
    return time, error


def quasi_static_error(
    time_s: np.ndarray,
    link_rad: np.ndarray,
    reference_rad: np.ndarray,
    push_start_s: float,
    after_push_s: float,
    window_s: float = DEFAULT_WINDOW_S,
) -> QuasiStaticError:
    """The error at `after_push_s` after the push (mean over a window, NaN samples skipped)."""
    time, error = _error_signal(time_s, link_rad, reference_rad)
    if not (after_push_s >= 0 and window_s > 0):
        raise ValueError("after_push_s must be >= 0 and window_s > 0")
    centre = push_start_s + after_push_s
    inside = (time >= centre - window_s / 2) & (time <= centre + window_s / 2)
    values = error[inside]
    values = values[np.isfinite(values)]
    if values.size == 0:
        covered = f"{time[0]} .. {time[-1]} s" if time.size else "nothing"
        raise ValueError(
            f"the run has no valid sample {after_push_s} s after the push (t = {centre} s); "
            f"it covers {covered}"
        )
    return QuasiStaticError(after_push_s, window_s, float(np.mean(values)))


def _linear_fit(t: np.ndarray, e: np.ndarray, tau: float) -> tuple[np.ndarray, float]:
    basis = np.column_stack([np.ones_like(t), np.exp(-t / tau)])
    coefficients, *_ = np.linalg.lstsq(basis, e, rcond=None)
    residual = e - basis @ coefficients
    return coefficients, float(residual @ residual)


def _fit_window(
    time: np.ndarray, error: np.ndarray, start_s: float, end_s: float | None
) -> tuple[np.ndarray, np.ndarray]:
    """The error's valid samples in [start_s, end_s] (time from start_s), at least 10."""
    end = time[-1] if end_s is None else end_s
    if time.size and time[-1] <= start_s:
        raise SlowModeFitError(
            f"the run ends at {time[-1]:g} s, before the fit's window starts at {start_s:g} s"
        )
    inside = (time >= start_s) & (time <= end) & np.isfinite(error)
    if np.count_nonzero(inside) < 10:
        raise SlowModeFitError(
            f"only {np.count_nonzero(inside)} valid samples in [{start_s}, {end}] s"
        )
    return time[inside] - start_s, error[inside]


def _minimize_on(function: Callable[[float], float], bounds: tuple[float, float]) -> Any:
    """scipy's bounded scalar minimisation (scipy.optimize imported here: every command
    imports the experiments, few fit a mode)."""
    import scipy.optimize

    return scipy.optimize.minimize_scalar(
        function, bounds=bounds, method="bounded", options={"xatol": 1e-6}
    )


def fit_slow_mode(
    time_s: np.ndarray,
    link_rad: np.ndarray,
    reference_rad: np.ndarray,
    start_s: float,
    end_s: float | None = None,
    *,
    min_time_constant_s: float = MIN_TIME_CONSTANT_S,
    max_time_constant_s: float = MAX_TIME_CONSTANT_S,
    min_record_time_constants: float = MIN_RECORD_TIME_CONSTANTS,
) -> SlowModeFit:
    """Fit e(t) = e_eq + A exp(-(t - start_s) / tau) to link - reference over [start_s, end_s].

    Start after the fast transients (a few tenths of a second after the push on the testbed).
    For each tau the best (e_eq, A) is linear least squares; tau minimises the residual on a log
    scale within [min_time_constant_s, max_time_constant_s]. Raises SlowModeFitError when the
    result would not mean anything: fewer than 10 samples, tau at the edge of the search, a
    record shorter than min_record_time_constants x tau (e_eq would be an extrapolation),
    A below MIN_AMPLITUDE_NOISE_RATIO x the residual rms, or standard errors above
    MAX_RELATIVE_STD of tau or of |A|.
    """
    t, e = _fit_window(*_error_signal(time_s, link_rad, reference_rad), start_s, end_s)
    if not 0 < min_time_constant_s < max_time_constant_s:
        raise ValueError("need 0 < min_time_constant_s < max_time_constant_s")
    bounds = (math.log(min_time_constant_s), math.log(max_time_constant_s))
    search = _minimize_on(lambda log_tau: _linear_fit(t, e, math.exp(log_tau))[1], bounds)
    tau = math.exp(float(search.x))
    (equilibrium, amplitude), rss = _linear_fit(t, e, tau)
    span = float(t[-1])
    if min(abs(search.x - bounds[0]), abs(search.x - bounds[1])) < 1e-3:
        raise SlowModeFitError(
            f"the time constant is not identifiable: the best fit lies at the edge of the "
            f"search, tau = {tau:.3g} s (searched {min_time_constant_s} .. {max_time_constant_s})"
        )
    residual_rms = math.sqrt(rss / t.size)
    if abs(amplitude) < MIN_AMPLITUDE_NOISE_RATIO * residual_rms:
        raise SlowModeFitError(
            f"no decaying mode above the noise: amplitude {abs(amplitude):.3g} rad against a "
            f"residual rms of {residual_rms:.3g} rad"
        )
    if span < min_record_time_constants * tau:
        raise SlowModeFitError(
            f"the record covers {span:.3g} s, {span / tau:.2f} time constants of the fitted "
            f"{tau:.3g} s: the equilibrium would be an extrapolation (need a run of at least "
            f"{min_record_time_constants * tau:.3g} s after t = {start_s} s)"
        )
    decay = np.exp(-t / tau)
    jacobian = np.column_stack([np.ones_like(t), decay, amplitude * decay * t / tau**2])
    variance = rss / max(t.size - 3, 1)
    try:
        covariance = variance * np.linalg.inv(jacobian.T @ jacobian)
    except np.linalg.LinAlgError:
        raise SlowModeFitError("the fit's covariance is singular") from None
    equilibrium_std = math.sqrt(max(covariance[0, 0], 0.0))
    tau_std = math.sqrt(max(covariance[2, 2], 0.0))
    if tau_std > MAX_RELATIVE_STD * tau or equilibrium_std > MAX_RELATIVE_STD * abs(amplitude):
        raise SlowModeFitError(
            f"the fit is too uncertain: tau = {tau:.3g} +- {tau_std:.2g} s, "
            f"e_eq = {equilibrium:.3g} +- {equilibrium_std:.2g} rad"
        )
    return SlowModeFit(
        equilibrium_error_rad=float(equilibrium),
        time_constant_s=tau,
        amplitude_rad=float(amplitude),
        start_s=float(start_s),
        end_s=float(start_s + span),
        equilibrium_std_rad=equilibrium_std,
        time_constant_std_s=tau_std,
        residual_rms_rad=residual_rms,
    )
