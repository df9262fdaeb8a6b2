"""A gap in the samples (a skipped deadline, a failed read) must not look like motion.

Checked against the nominal discrete servo itself: without a disturbance the DOB's estimate of
(9)-(11) is exactly zero at every tick, so any non-zero value after a gap is the gap misread.
"""

from __future__ import annotations

import numpy as np
import pytest

from controller.dob import DisturbanceObserver, nominal_servo_coefficients

DT = 0.005
KP = np.array([10.0])


def _servo_run(n_ticks: int, command: float) -> np.ndarray:
    """theta_m(k+1) = a theta_m(k) + b u: the nominal servo the DOB inverts, from rest at 0."""
    a, b = nominal_servo_coefficients(KP, DT, "zoh")
    theta = np.zeros(n_ticks)
    for k in range(1, n_ticks):
        theta[k] = a[0] * theta[k - 1] + b[0] * command
    return theta


@pytest.mark.parametrize("resync", [True, False])
def test_a_skipped_tick_is_not_read_as_a_disturbance_after_resync(resync: bool) -> None:
    command = np.array([0.3])
    theta = _servo_run(40, command[0])
    dob = DisturbanceObserver(KP, cutoff_hz=11.35, dt_s=DT, kdist=1.0, method="zoh")
    dob.reset(theta[:1])
    estimates = []
    for k in range(1, 40):
        if k == 20:
            if resync:
                dob.resync()
            continue  # tick 20 is lost: the next update sees theta two periods later
        estimates.append(float(dob.update(theta[k : k + 1], command)[0]))
    worst = max(abs(e) for e in estimates)
    if resync:
        assert worst < 1e-12
    else:  # what resync prevents: the gap's motion read through 1/b as a disturbance
        assert worst > 1e-3
