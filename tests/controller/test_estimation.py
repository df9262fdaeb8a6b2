"""State estimation from quantised encoders: noise within the bounds derived in estimation.py."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controller.estimation import (
    LINK_ENCODER_RESOLUTION_RAD,
    MOTOR_ENCODER_RESOLUTION_RAD,
    FlexibleJointStateEstimator,
    velocity_noise_bound_rad_s,
    velocity_noise_rms_rad_s,
)

DT_S = 0.005


def _trajectory(n_ticks: int, seed: int) -> np.ndarray:
    """A smooth link motion of a few tenths of a radian (many quanta per tick)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n_ticks) * DT_S
    motion = np.zeros(n_ticks)
    for _ in range(4):
        motion += rng.uniform(0.05, 0.3) * np.sin(
            2 * math.pi * rng.uniform(0.2, 3.0) * t + rng.uniform(0, 6)
        )
    return motion


def _link_velocity(angles: np.ndarray, cutoff_hz: float | None) -> np.ndarray:
    estimator = FlexibleJointStateEstimator(1, DT_S, cutoff_hz)
    estimator.reset(np.zeros(1), angles[:1])
    return np.array(
        [estimator.update(np.zeros(1), angles[k : k + 1])[2] for k in range(len(angles))]
    )


def test_resolutions_are_the_encoders() -> None:
    motor_quantum, link_quantum = MOTOR_ENCODER_RESOLUTION_RAD, LINK_ENCODER_RESOLUTION_RAD
    assert motor_quantum == pytest.approx(1.2518e-5, rel=1e-4)
    assert link_quantum == pytest.approx(6.3915e-6, rel=1e-4)
    assert velocity_noise_bound_rad_s(LINK_ENCODER_RESOLUTION_RAD, DT_S) == pytest.approx(
        1.278e-3, rel=1e-3
    )
    assert velocity_noise_rms_rad_s(LINK_ENCODER_RESOLUTION_RAD, DT_S) == pytest.approx(
        5.22e-4, rel=1e-2
    )


@pytest.mark.parametrize("cutoff_hz", [None, 20.0])
@pytest.mark.parametrize("rounding", [np.round, np.floor])
def test_link_velocity_noise_within_the_derived_bounds(cutoff_hz: float | None, rounding) -> None:
    q = LINK_ENCODER_RESOLUTION_RAD
    exact = _trajectory(20_000, seed=5)
    quantised = rounding(exact / q) * q
    noise = _link_velocity(quantised, cutoff_hz) - _link_velocity(exact, cutoff_hz)
    bound = velocity_noise_bound_rad_s(q, DT_S, cutoff_hz)
    rms = velocity_noise_rms_rad_s(q, DT_S, cutoff_hz)
    assert np.max(np.abs(noise)) < bound
    assert np.max(np.abs(noise)) > 0.6 * bound  # the bound is not loose
    assert np.sqrt(np.mean(noise**2)) == pytest.approx(rms, rel=0.05)


def test_state_increment_and_deflection() -> None:
    estimator = FlexibleJointStateEstimator(2, DT_S)
    estimator.reset(np.array([0.1, 0.2]), np.array([0.1, 0.19]))
    np.testing.assert_array_equal(estimator.increment, np.zeros(6))
    previous = estimator.state.copy()
    state = estimator.update(np.array([0.11, 0.2]), np.array([0.1005, 0.19]))
    np.testing.assert_allclose(state, [0.11, 0.2, 0.1005, 0.19, 0.0005 / DT_S, 0.0], atol=1e-12)
    np.testing.assert_allclose(estimator.increment, state - previous, atol=1e-15)
    np.testing.assert_allclose(estimator.deflection_rad, [0.1005 - 0.11, 0.19 - 0.2], atol=1e-15)


def test_ramp_velocity_is_exact_after_the_filter_settles() -> None:
    angles = 0.3 * np.arange(400) * DT_S  # 0.3 rad/s
    np.testing.assert_allclose(_link_velocity(angles, None)[1:], 0.3, rtol=1e-9)
    filtered = _link_velocity(angles, 20.0)
    assert filtered[-1] == pytest.approx(0.3, rel=1e-9)


def test_bad_cutoff_is_refused() -> None:
    with pytest.raises(ValueError, match="cut-off"):
        FlexibleJointStateEstimator(1, DT_S, 0.0)
    with pytest.raises(ValueError, match="dt_s"):
        FlexibleJointStateEstimator(1, -1.0)
