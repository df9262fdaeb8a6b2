"""State estimation from quantised encoders: noise within the bounds derived in estimation.py,
for the resolutions the caller passes; the lab's zero link-velocity increment."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controller.estimation import (
    FlexibleJointStateEstimator,
    deflection_error_bound_rad,
    velocity_noise_bound_rad_s,
    velocity_noise_rms_rad_s,
)

DT_S = 0.005
# Example resolutions (the testbed's encoders): the product takes them from its drivers.
LINK_QUANTUM_RAD = 2 * math.pi / 983_040
MOTOR_QUANTUM_RAD = 2 * math.pi / 501_923


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


def test_deflection_error_stays_within_half_a_quantum_of_each_encoder() -> None:
    """Both encoders round: |error of theta_j - theta_m| <= (q_m + q_j) / 2, and it gets close."""
    rng = np.random.default_rng(11)
    motor = rng.uniform(-1.0, 1.0, 50_000)
    link = motor + rng.uniform(-0.01, 0.01, motor.size)
    measured = np.round(link / LINK_QUANTUM_RAD) * LINK_QUANTUM_RAD - (
        np.round(motor / MOTOR_QUANTUM_RAD) * MOTOR_QUANTUM_RAD
    )
    error = np.abs(measured - (link - motor))
    bound = deflection_error_bound_rad(MOTOR_QUANTUM_RAD, LINK_QUANTUM_RAD)
    assert np.max(error) <= bound + 1e-15
    assert np.max(error) > 0.95 * bound


@pytest.mark.parametrize("q", [LINK_QUANTUM_RAD, MOTOR_QUANTUM_RAD])
@pytest.mark.parametrize("cutoff_hz", [None, 20.0])
@pytest.mark.parametrize("rounding", [np.round, np.floor])
def test_link_velocity_noise_within_the_derived_bounds(
    cutoff_hz: float | None, rounding, q: float
) -> None:
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


def test_the_labs_zero_velocity_increment_keeps_the_velocity_out_of_the_increment() -> None:
    """The lab fed zero for d dtheta_j; the state still carries the difference velocity."""
    angles = 0.3 * (np.arange(50) * DT_S) ** 2  # accelerating: the velocity changes every tick
    zero = FlexibleJointStateEstimator(1, DT_S, link_velocity_increment="zero")
    difference = FlexibleJointStateEstimator(1, DT_S)
    for estimator in (zero, difference):
        estimator.reset(np.zeros(1), angles[:1])
    for k in range(1, angles.size):
        zero.update(np.zeros(1), angles[k : k + 1])
        difference.update(np.zeros(1), angles[k : k + 1])
        step = angles[k] - angles[k - 1]
        np.testing.assert_allclose(zero.increment, [0.0, step, 0.0], atol=1e-15)
        assert zero.link_velocity_rad_s[0] == pytest.approx(step / DT_S)
        if k > 1:  # second difference over dt: 2 x 0.3 x dt^2 / dt
            assert difference.increment[2] == pytest.approx(0.6 * DT_S, rel=1e-9)
    with pytest.raises(ValueError, match="link_velocity_increment"):
        FlexibleJointStateEstimator(1, DT_S, link_velocity_increment="filtered")  # type: ignore[arg-type]


def test_bad_cutoff_is_refused() -> None:
    with pytest.raises(ValueError, match="cut-off"):
        FlexibleJointStateEstimator(1, DT_S, 0.0)
    with pytest.raises(ValueError, match="dt_s"):
        FlexibleJointStateEstimator(1, -1.0)
