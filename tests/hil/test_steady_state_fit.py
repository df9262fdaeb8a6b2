"""hil.experiments.steady_state on synthetic signals with known answers: the quasi-static error
at a stated time, the slow mode's equilibrium and time constant, and honest failures."""

from __future__ import annotations

import numpy as np
import pytest

from hil.experiments.steady_state import SlowModeFitError, fit_slow_mode, quasi_static_error

DT_S = 0.005


def _signal(
    duration_s: float, equilibrium: float, amplitude: float, tau: float, noise: float, seed: int = 1
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """time, link, reference with link - reference = e_eq + A exp(-t / tau) + white noise."""
    rng = np.random.default_rng(seed)
    time = np.arange(0.0, duration_s, DT_S)
    reference = np.full(time.size, 0.2)
    error = equilibrium + amplitude * np.exp(-time / tau) + rng.normal(0.0, noise, time.size)
    return time, reference + error, reference


def test_fit_recovers_a_known_slow_mode_under_noise() -> None:
    time, link, reference = _signal(60.0, 0.004, -0.03, 15.0, noise=2e-4)
    fit = fit_slow_mode(time, link, reference, start_s=0.0)
    assert fit.time_constant_s == pytest.approx(15.0, rel=0.02)
    assert fit.equilibrium_error_rad == pytest.approx(0.004, abs=2e-4)
    assert fit.amplitude_rad == pytest.approx(-0.03, rel=0.02)
    assert fit.residual_rms_rad == pytest.approx(2e-4, rel=0.05)
    # the standard errors are honest: the truth lies within a few of them
    assert abs(fit.time_constant_s - 15.0) < 4 * fit.time_constant_std_s
    assert abs(fit.equilibrium_error_rad - 0.004) < 4 * fit.equilibrium_std_rad
    np.testing.assert_allclose(fit.value_at(time), 0.004 - 0.03 * np.exp(-time / 15.0), atol=3e-4)


def test_fit_from_a_later_start_refers_the_amplitude_to_that_start() -> None:
    time, link, reference = _signal(60.0, 0.0, 0.02, 10.0, noise=0.0)
    fit = fit_slow_mode(time, link, reference, start_s=5.0, end_s=50.0)
    assert fit.time_constant_s == pytest.approx(10.0, rel=1e-6)
    assert fit.amplitude_rad == pytest.approx(0.02 * np.exp(-0.5), rel=1e-6)
    assert fit.start_s == 5.0 and fit.end_s == pytest.approx(50.0, abs=DT_S)


def test_a_record_shorter_than_the_time_constant_is_refused() -> None:
    """A 5 s impact run ends inside a 15 s mode: its end is not an equilibrium."""
    time, link, reference = _signal(5.0, 0.0, -0.03, 15.0, noise=1e-5)
    with pytest.raises(SlowModeFitError, match="extrapolation"):
        fit_slow_mode(time, link, reference, start_s=1.5)


def test_a_flat_record_has_no_mode_to_fit() -> None:
    time, link, reference = _signal(30.0, 0.01, 0.0, 15.0, noise=1e-4)
    with pytest.raises(SlowModeFitError):
        fit_slow_mode(time, link, reference, start_s=0.0)


def test_a_mode_slower_than_the_search_is_refused() -> None:
    time, link, reference = _signal(20.0, 0.0, -0.03, 1e5, noise=1e-6)
    with pytest.raises(SlowModeFitError):
        fit_slow_mode(time, link, reference, start_s=0.0, max_time_constant_s=100.0)


def test_too_few_samples_are_refused() -> None:
    time, link, reference = _signal(1.0, 0.0, -0.03, 0.2, noise=0.0)
    with pytest.raises(SlowModeFitError, match="valid samples"):
        fit_slow_mode(time, link, reference, start_s=0.98)


def test_quasi_static_error_is_the_mean_error_at_the_stated_time() -> None:
    time, link, reference = _signal(10.0, 0.0, -0.03, 15.0, noise=0.0)
    error = quasi_static_error(time, link, reference, push_start_s=1.0, after_push_s=3.0)
    window = (time >= 3.95) & (time <= 4.05)
    assert error.error_rad == pytest.approx(np.mean(-0.03 * np.exp(-time[window] / 15.0)))
    assert error.error_rad == pytest.approx(-0.03 * np.exp(-4.0 / 15.0), rel=1e-4)
    assert error.after_push_s == 3.0 and error.window_s == 0.1
    link_with_gap = link.copy()
    link_with_gap[window] = np.nan
    with pytest.raises(ValueError, match="no valid sample"):
        quasi_static_error(time, link_with_gap, reference, push_start_s=1.0, after_push_s=3.0)


def test_bad_inputs_are_refused() -> None:
    time, link, reference = _signal(10.0, 0.0, -0.03, 15.0, noise=0.0)
    with pytest.raises(ValueError, match="one length"):
        fit_slow_mode(time, link[:-1], reference, start_s=0.0)
    with pytest.raises(ValueError, match="increase"):
        fit_slow_mode(time[::-1], link, reference, start_s=0.0)
