"""Quintic swing foot: boundary conditions, apex height, derivatives (checked analytically)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controller.walking import SwingFootTrajectory, quintic_blend


def test_quintic_blend_boundary_values():
    b, db, ddb = quintic_blend(np.array([0.0, 0.5, 1.0]))
    assert b.tolist() == [0.0, 0.5, 1.0]  # 10/8 - 15/16 + 6/32 = 1/2 exactly
    assert db[[0, 2]].tolist() == [0.0, 0.0] and ddb[[0, 2]].tolist() == [0.0, 0.0]
    assert db[1] == pytest.approx(30 / 16)  # 30 s^2 (1 - s)^2 at 1/2: the peak rate
    assert ddb[1] == 0.0


def test_quintic_blend_derivatives_are_those_of_the_polynomial():
    s = np.linspace(0.0, 1.0, 11)
    b, db, ddb = quintic_blend(s)
    poly = np.polynomial.Polynomial([0, 0, 0, 10, -15, 6])
    assert np.allclose(b, poly(s), atol=1e-15)
    assert np.allclose(db, poly.deriv(1)(s), atol=1e-13)
    assert np.allclose(ddb, poly.deriv(2)(s), atol=1e-12)


SWING = SwingFootTrajectory(
    start_xy_m=(0.0, -0.127794),
    end_xy_m=(0.4, -0.1),
    start_yaw_rad=0.0,
    end_yaw_rad=0.2,
    height_m=0.05,
    duration_s=0.8,
)


def test_lift_off_and_touchdown_have_zero_velocity_and_acceleration():
    pose, vel, acc = SWING.evaluate(np.array([0.0, 0.8]))
    assert pose[0].tolist() == [0.0, -0.127794, 0.0, 0.0]
    assert pose[1] == pytest.approx([0.4, -0.1, 0.0, 0.2], abs=1e-15)
    assert np.all(vel == 0.0) and np.all(acc == 0.0)


def test_apex_height_is_reached_at_mid_swing_and_never_exceeded():
    t = np.linspace(0.0, 0.8, 1601)
    pose, vel, acc = SWING.evaluate(t)
    assert pose[800, 2] == 0.05  # h b(1) = h, exactly
    assert vel[800, 2] == 0.0 and acc[800, 2] == 0.0  # both halves meet flat: C2 at the apex
    assert pose[:, 2].max() == 0.05 and pose[:, 2].min() == 0.0
    assert pose[800, :2] == pytest.approx([0.2, -0.113897])  # b(1/2) = 1/2: half-way
    # Height at a quarter of the swing: h b(1/2) = h / 2.
    assert pose[400, 2] == pytest.approx(0.025, abs=1e-15)
    # Peak vertical speed: h * b'(1/2) * 2 / T = 0.05 * 1.875 * 2.5.
    assert np.abs(vel[:, 2]).max() == pytest.approx(0.05 * 1.875 * 2.5)


def test_velocity_and_acceleration_are_the_time_derivatives():
    t = np.linspace(0.0, 0.8, 8001)
    pose, vel, acc = SWING.evaluate(t)
    dt = t[1] - t[0]
    assert np.allclose(np.gradient(pose, dt, axis=0)[1:-1], vel[1:-1], atol=1e-5)
    # The height's jerk reverses at the apex (+-h b3(1) (2/T)^3 = +-46.9 m/s^3, b3 = b'''):
    # a central difference across it is off by up to jerk * dt / 2 there.
    jerk_at_apex = 0.05 * 60.0 * (2.0 / 0.8) ** 3
    assert np.allclose(np.gradient(vel, dt, axis=0)[1:-1], acc[1:-1], atol=jerk_at_apex * dt)


def test_yaw_takes_the_short_way_round():
    swing = SwingFootTrajectory((0, 0), (0, 0), 3.0, -3.0, 0.0, 1.0)
    pose, _, _ = swing.evaluate(np.array([0.5, 1.0]))
    assert pose[0, 3] == pytest.approx(3.0 + (2 * math.pi - 6.0) / 2)
    assert math.cos(pose[1, 3]) == pytest.approx(math.cos(-3.0))


def test_times_outside_the_swing_are_clipped_to_its_ends():
    pose, vel, _ = SWING.evaluate(np.array([-0.1, 0.9]))
    assert pose[0].tolist() == [0.0, -0.127794, 0.0, 0.0]
    assert pose[1, 0] == pytest.approx(0.4) and np.all(vel == 0)


@pytest.mark.parametrize(("field", "value"), [("duration_s", 0.0), ("height_m", -0.01)])
def test_rejects_bad_parameters(field, value):
    values = {
        "start_xy_m": (0, 0),
        "end_xy_m": (0, 0),
        "start_yaw_rad": 0.0,
        "end_yaw_rad": 0.0,
        "height_m": 0.05,
        "duration_s": 0.8,
    } | {field: value}
    with pytest.raises(ValueError, match=field):
        SwingFootTrajectory(**values)
