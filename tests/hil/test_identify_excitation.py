"""The identification chirp: its limits, its band, its refusals."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from hil.identify import ChirpExcitation, chirp_goal_offsets, peak_motor_torque_bound_nm

DEFAULT = ChirpExcitation()


def test_sampled_goal_respects_amplitude_rate_and_starts_and_ends_at_rest() -> None:
    trajectory = chirp_goal_offsets(DEFAULT)
    offset = trajectory.goal_offset_rad
    assert len(offset) == round(DEFAULT.duration_s / DEFAULT.period_s)
    assert np.max(np.abs(offset)) <= DEFAULT.amplitude_rad
    assert np.max(np.abs(offset)) > 0.95 * DEFAULT.amplitude_rad  # the amplitude is used
    steps = np.abs(np.diff(offset, prepend=0.0, append=0.0))
    assert steps.max() <= DEFAULT.max_goal_rate_rad_s * DEFAULT.period_s
    settle = int(DEFAULT.settle_duration_s / DEFAULT.period_s)
    assert np.all(offset[:settle] == 0.0)
    assert np.all(offset[-settle:] == 0.0)
    assert trajectory.validation_start_s == DEFAULT.settle_duration_s + 30.0


def _crossings(offset: np.ndarray, time_s: np.ndarray, start_s: float, stop_s: float) -> int:
    inside = (time_s >= start_s) & (time_s < stop_s) & (offset != 0.0)
    signs = np.signbit(offset[inside])
    return int(np.count_nonzero(signs[1:] != signs[:-1]))


def _frequency_near(offset: np.ndarray, time_s: np.ndarray, at_s: float, span_s: float) -> float:
    """Mean frequency over [at - span/2, at + span/2] from zero crossings."""
    return _crossings(offset, time_s, at_s - span_s / 2, at_s + span_s / 2) / (2 * span_s)


@pytest.mark.parametrize("fraction", [0.2, 0.5, 0.8])
def test_fit_sweep_phase_is_that_of_a_logarithmic_chirp(fraction: float) -> None:
    """Zero crossings between the sweep's start and a point in it: one per pi of the phase
    phi(tau) = w0 (exp(c tau) - 1) / c, c = ln(f1/f0) / T (to within a crossing)."""
    trajectory = chirp_goal_offsets(DEFAULT)
    f0, f1 = DEFAULT.start_frequency_hz, DEFAULT.stop_frequency_hz
    sweep = DEFAULT.fit_sweep_duration_s
    tau = fraction * sweep
    rate = math.log(f1 / f0) / sweep
    phase = 2 * math.pi * f0 * math.expm1(rate * tau) / rate
    start = DEFAULT.settle_duration_s
    counted = _crossings(trajectory.goal_offset_rad, trajectory.time_s, start, start + tau)
    assert abs(counted - phase / math.pi) <= 1.5


def test_validation_sweep_runs_back_down() -> None:
    trajectory = chirp_goal_offsets(DEFAULT)
    start = DEFAULT.validation_start_s
    early = _frequency_near(trajectory.goal_offset_rad, trajectory.time_s, start + 2.0, 1.0)
    late = _frequency_near(trajectory.goal_offset_rad, trajectory.time_s, start + 10.0, 2.0)
    assert early > 3 * late


def test_envelope_is_rate_limited_at_high_frequency() -> None:
    """Above r/A the amplitude falls as 0.85 r / omega: the goal's rate stays just below r."""
    trajectory = chirp_goal_offsets(DEFAULT)
    t, offset = trajectory.time_s, trajectory.goal_offset_rad
    at = DEFAULT.settle_duration_s + 0.8 * DEFAULT.fit_sweep_duration_s
    f0, f1 = DEFAULT.start_frequency_hz, DEFAULT.stop_frequency_hz
    omega = 2 * math.pi * f0 * (f1 / f0) ** 0.8
    window = (t > at - 0.2) & (t < at + 0.2)
    peak = np.max(np.abs(offset[window]))
    assert peak == pytest.approx(0.85 * DEFAULT.max_goal_rate_rad_s / omega, rel=0.05)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"holding_angle_rad": 0.75}, "position limits"),
        ({"stop_frequency_hz": 40.0}, "Nyquist"),
        ({"taper_duration_s": 20.0}, "taper"),
        ({"amplitude_rad": -0.1}, "amplitude_rad"),
        ({"start_frequency_hz": 12.0}, "stop_frequency_hz must exceed"),
    ],
)
def test_refuses_what_would_break_a_limit(change: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        ChirpExcitation(**change)


def test_refuses_an_envelope_that_would_move_the_goal_too_fast() -> None:
    """A steep taper on a large low-frequency swing: the envelope's own slope breaks the rate."""
    steep = dataclasses.replace(
        DEFAULT,
        amplitude_rad=0.5,
        max_angle_rad=1.0,
        min_angle_rad=-1.0,
        taper_duration_s=0.05,
        start_frequency_hz=0.05,
    )
    with pytest.raises(ValueError, match="rad/s, above the limit"):
        chirp_goal_offsets(steep)


def test_peak_torque_bound_adds_its_terms() -> None:
    """Hand calculation with round figures: 0.5*10 + 2 + (0.2 + 0.3)*2*10*1.5 + 50*10*1.5*0.005."""
    excitation = dataclasses.replace(DEFAULT, max_goal_rate_rad_s=1.5)
    bound = peak_motor_torque_bound_nm(
        excitation,
        link_inertia_kg_m2=0.3,
        motor_inertia_kg_m2=0.2,
        gravity_moment_kg_m=0.5,
        position_gain_per_s=10.0,
        velocity_gain_nms_per_rad=50.0,
        coulomb_friction_nm=2.0,
        gravity_m_s2=10.0,
    )
    assert bound == pytest.approx(5.0 + 2.0 + 15.0 + 3.75)
