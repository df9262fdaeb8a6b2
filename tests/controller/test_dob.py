"""DOB (9)-(11), (18): steady state, transfer function d -> d_hat, static compliance, Kdist."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controller.dob import (
    LAB_DOB_CUTOFF_HZ,
    DisturbanceObserver,
    discrete_q_response,
    quantisation_noise_rms_rad,
)

DT_S = 0.005
KP = 10.0


def _nominal_servo(method: str = "zoh") -> tuple[float, float]:
    """The nominal servo (4) sampled at 5 ms, written from the analysis (not from dob.py)."""
    if method == "zoh":
        a = math.exp(-KP * DT_S)
        return a, 1 - a
    return 1 - KP * DT_S, KP * DT_S


def _run_dob_loop(
    observer: DisturbanceObserver,
    disturbance: np.ndarray,
    uc: float = 0.2,
    method: str = "zoh",
) -> tuple[np.ndarray, np.ndarray]:
    """(9)-(10) with P = Pn: theta_m = P (u' + d), u' = uc + d_hat. Returns d_hat and theta_m."""
    a, b = _nominal_servo(method)
    theta_m = np.array([uc])
    observer.reset(theta_m)
    sent = theta_m.copy()
    d_hats, angles = [], []
    for d in disturbance:
        d_hat = observer.update(theta_m, sent).copy()
        sent = uc + d_hat
        d_hats.append(d_hat[0])
        angles.append(theta_m[0])
        theta_m = a * theta_m + b * (sent + d)
    return np.array(d_hats), np.array(angles)


@pytest.mark.parametrize(
    "cutoff_hz, pole",
    [
        (LAB_DOB_CUTOFF_HZ, 0.7),  # the lab's filter, 0.3 / (1 - 0.7 z^-1)
        (11.4, 0.698974),  # the testbed configuration's rounded cut-off: not the lab's pole
        (2.0, 0.939101),
    ],
)
def test_filter_step_response_is_the_continuous_one_at_the_ticks(
    cutoff_hz: float, pole: float
) -> None:
    """ZOH step invariance: q(k) for a held unit raw estimate is 1 - exp(-2 pi fc k dt), the
    continuous Q(s)'s step response sampled; the pole is exp(-2 pi fc dt), written out here
    (0.7 for 11.3533 Hz, 0.698974 for 11.4 Hz)."""
    observer = DisturbanceObserver(np.array([KP]), cutoff_hz, DT_S, 1.0)
    assert observer.filter_pole == pytest.approx(pole, abs=1e-6)
    observer.reset(np.zeros(1))
    a, b = _nominal_servo()
    theta_m, sent = np.zeros(1), np.zeros(1)  # raw = 1 per tick: the servo lags a unit
    for k in range(1, 30):
        theta_m = a * theta_m + b * (sent + 1.0)  # a unit input disturbance
        q = observer.update(theta_m, sent)[0]
        assert q == pytest.approx(1 - math.exp(-2 * math.pi * cutoff_hz * k * DT_S), abs=1e-12)
    lab_cutoff = LAB_DOB_CUTOFF_HZ
    assert lab_cutoff == pytest.approx(-math.log(0.7) / (2 * math.pi * DT_S), rel=1e-15)
    assert lab_cutoff == pytest.approx(11.3533, abs=1e-4)


def test_the_labs_pole_can_be_given_directly_and_not_with_a_cutoff_too() -> None:
    observer = DisturbanceObserver(np.array([KP]), None, DT_S, 1.0, filter_pole=0.7)
    assert observer.filter_pole == 0.7
    observer.reset(np.zeros(1))
    a, b = _nominal_servo()
    theta_m = a * np.zeros(1) + b * np.ones(1)
    assert observer.update(theta_m, np.zeros(1))[0] == pytest.approx(0.3, abs=1e-12)
    with pytest.raises(ValueError, match="not both"):
        DisturbanceObserver(np.array([KP]), 11.4, DT_S, 1.0, filter_pole=0.7)
    with pytest.raises(ValueError, match="pole"):
        DisturbanceObserver(np.array([KP]), None, DT_S, 1.0, filter_pole=1.0)


@pytest.mark.parametrize("kdist", [0.0, 0.5, 1.0, -0.5])
@pytest.mark.parametrize("method", ["zoh", "euler"])
def test_constant_disturbance_gives_kdist_d_and_the_compliance_of_18(
    kdist: float, method: str
) -> None:
    """d_hat -> Kdist d, and theta_m -> uc + (1 + Kdist) d (18) with uc held constant."""
    observer = DisturbanceObserver(np.array([KP]), LAB_DOB_CUTOFF_HZ, DT_S, kdist, method)  # type: ignore[arg-type]
    d, uc = 0.03, 0.2
    d_hat, theta_m = _run_dob_loop(observer, np.full(600, d), uc, method)
    assert d_hat[-1] == pytest.approx(kdist * d, abs=1e-12)
    assert theta_m[-1] == pytest.approx(uc + (1 + kdist) * d, abs=1e-10)
    assert observer.filtered_estimate_rad[0] == pytest.approx(d, abs=1e-12)


def test_raw_estimate_is_the_disturbance_one_tick_late() -> None:
    """With the exact sampled nominal servo the inverse model recovers d(k-1) exactly."""
    observer = DisturbanceObserver(np.array([KP]), 1e6, DT_S, 1.0)  # Q ~ 1: alpha ~ 0
    rng = np.random.default_rng(4)
    d = rng.normal(scale=0.01, size=50)
    d_hat, _ = _run_dob_loop(observer, d)
    np.testing.assert_allclose(d_hat[1:], d[:-1], atol=1e-12)


@pytest.mark.parametrize("frequency_hz", [0.5, 2.0, 8.0, 20.0, 60.0])
def test_d_to_d_hat_is_kdist_times_the_sampled_q(frequency_hz: float) -> None:
    kdist = 0.8
    observer = DisturbanceObserver(np.array([KP]), LAB_DOB_CUTOFF_HZ, DT_S, kdist)
    n_ticks = 4000
    k = np.arange(n_ticks)
    omega_dt = 2 * math.pi * frequency_hz * DT_S
    d = 0.01 * np.sin(omega_dt * k)
    d_hat, _ = _run_dob_loop(observer, d)
    # steady-state phasor by least squares over the last half
    tail = slice(n_ticks // 2, None)
    basis = np.column_stack([np.sin(omega_dt * k[tail]), np.cos(omega_dt * k[tail])])
    sin_c, cos_c = np.linalg.lstsq(basis, d_hat[tail], rcond=None)[0]
    measured = (sin_c + 1j * cos_c) / 0.01
    expected = kdist * discrete_q_response(np.array(frequency_hz), LAB_DOB_CUTOFF_HZ, DT_S)
    assert abs(measured - expected) < 1e-9
    # ... which is Kdist (1 - alpha) / (z - alpha) written out here, and close to Kdist Q(jw)
    alpha = 0.7
    z = np.exp(1j * omega_dt)
    assert abs(expected - kdist * (1 - alpha) / (z - alpha)) < 1e-12
    if frequency_hz <= 2.0:
        continuous = kdist / (1 + 1j * frequency_hz / LAB_DOB_CUTOFF_HZ)
        assert abs(abs(measured) - abs(continuous)) < 0.01 * kdist


def test_set_kdist_changes_the_output_by_the_gain_change_only() -> None:
    """Without a ramp (kdist_ramp_ticks = 0) the next update carries the whole change."""
    observer = DisturbanceObserver(np.array([KP, KP]), LAB_DOB_CUTOFF_HZ, DT_S, [1.0, 0.2])
    a, b = _nominal_servo()
    d = np.array([0.02, -0.01])
    theta_m = np.zeros(2)
    observer.reset(theta_m)
    sent = np.zeros(2)
    for _ in range(400):  # steady state: q = d
        d_hat = observer.update(theta_m, sent)
        sent = d_hat.copy()
        theta_m = a * theta_m + b * (sent + d)
    before = observer.update(theta_m, sent).copy()
    q_before = observer.filtered_estimate_rad
    observer.set_kdist([0.5, 1.0])
    np.testing.assert_array_equal(observer.filtered_estimate_rad, q_before)  # state kept
    theta_m = a * theta_m + b * (before + d)
    after = observer.update(theta_m, before)
    np.testing.assert_allclose(after - before, (np.array([0.5, 1.0]) - [1.0, 0.2]) * d, atol=1e-12)


def test_dob_rejects_bad_configuration() -> None:
    with pytest.raises(ValueError, match="cut-off"):
        DisturbanceObserver(np.array([KP]), 0.0, DT_S, 1.0)
    with pytest.raises(ValueError, match="kdist needs 2 entries"):
        DisturbanceObserver(np.array([KP, KP]), 10.0, DT_S, [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="kdist must be finite"):
        DisturbanceObserver(np.array([KP]), 10.0, DT_S, math.nan)
    with pytest.raises(ValueError, match="servo_gain_per_s"):
        DisturbanceObserver(np.array([0.0]), 10.0, DT_S, 1.0)
    with pytest.raises(ValueError, match="discretisation"):
        DisturbanceObserver(np.array([KP]), 10.0, DT_S, 1.0, "tustin")  # type: ignore[arg-type]


@pytest.mark.parametrize("method", ["zoh", "euler"])
def test_motor_quantisation_noise_in_the_estimate_matches_the_derived_rms(method: str) -> None:
    quantum = 2 * math.pi / 501_923
    a, b = _nominal_servo(method)
    rng = np.random.default_rng(9)
    n_ticks = 40_000
    goals = np.cumsum(rng.normal(0.0, 0.01, n_ticks))  # the servo keeps moving
    angles = np.zeros(n_ticks)
    for k in range(1, n_ticks):
        angles[k] = a * angles[k - 1] + b * goals[k - 1]

    def estimates(measured: np.ndarray) -> np.ndarray:
        observer = DisturbanceObserver(np.array([KP]), LAB_DOB_CUTOFF_HZ, DT_S, 1.0, method)  # type: ignore[arg-type]
        observer.reset(measured[:1])
        return np.array(
            [observer.update(measured[k : k + 1], goals[k - 1 : k])[0] for k in range(1, n_ticks)]
        )

    noise = estimates(np.round(angles / quantum) * quantum) - estimates(angles)
    expected = quantisation_noise_rms_rad(quantum, KP, LAB_DOB_CUTOFF_HZ, DT_S, method)
    assert np.std(noise[100:]) == pytest.approx(expected, rel=0.05)
    if method == "zoh":
        assert expected == pytest.approx(2.36e-5, rel=0.01)
