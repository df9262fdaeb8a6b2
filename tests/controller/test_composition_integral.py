"""The "accumulated-integral" reading's arithmetic and its configuration rules (its physics is
tested against the emulated servo in test_bounded_contact.py)."""

from __future__ import annotations

import numpy as np
import pytest

from controller import Composition, ControllerParams


def test_the_dob_term_and_its_running_integral_are_both_accumulated() -> None:
    """I(k) = I(k-1) + g Kdist q(k); u(k) = u(k-1) + duc(k) + Kdist q(k) + I(k): with a constant
    DOB term c and no LQR increment, u(k) = u0 + k c + g c k (k + 1) / 2."""
    gain, term = 0.005 / 15.0, 0.002
    composition = Composition(1, "accumulated-integral", gain)
    composition.reset(np.array([0.1]), np.array([0.01]))
    for k in range(1, 201):
        u = composition.compose(np.zeros(1), np.array([term]), np.array([0.01]))[0]
        assert u == pytest.approx(0.1 + k * term + gain * term * k * (k + 1) / 2, abs=1e-15)
    assert composition.dob_integral[0] == pytest.approx(200 * gain * term)
    np.testing.assert_allclose(composition.uc + composition.d_hat + composition.ug, composition.u)


def test_without_a_dob_term_it_is_the_accumulated_reading() -> None:
    integral = Composition(2, "accumulated-integral", 0.01)
    lab = Composition(2, "accumulated")
    rng = np.random.default_rng(2)
    for composition in (integral, lab):
        composition.reset(np.array([0.1, -0.2]), np.zeros(2))
    for _ in range(50):
        increment, ug = rng.normal(size=2), rng.normal(size=2)
        np.testing.assert_array_equal(
            integral.compose(increment, np.zeros(2), ug), lab.compose(increment, np.zeros(2), ug)
        )


def test_the_integral_time_is_required_by_that_reading_and_refused_by_the_others() -> None:
    ControllerParams.paper(1, composition="accumulated-integral", dob_integral_time_s=15.0)
    with pytest.raises(ValueError, match="dob_integral_time_s"):
        ControllerParams.paper(1, composition="accumulated-integral")
    with pytest.raises(ValueError, match="dob_integral_time_s"):
        ControllerParams.paper(1, composition="accumulated", dob_integral_time_s=15.0)
    with pytest.raises(ValueError, match="dob_integral_time_s"):
        ControllerParams.paper(1, composition="accumulated-integral", dob_integral_time_s=0.0)
    with pytest.raises(ValueError, match="integral gain"):
        Composition(1, "accumulated-integral")
    with pytest.raises(ValueError, match="integral gain"):
        Composition(1, "literal", 0.01)
