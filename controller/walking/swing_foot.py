"""Swing-foot trajectory: quintic polynomials with zero velocity and acceleration at both ends.

The quintic blend b(s) = 10 s^3 - 15 s^4 + 6 s^5 on s in [0, 1] has b(0) = 0, b(1) = 1 and
b' = b'' = 0 at both ends (the unique quintic with these six conditions). Over a single support
of duration T, with s = t / T:

    horizontal (x, y) and yaw:  p(t) = p0 + (p1 - p0) b(s)
    height above the stance:    z(t) = h b(2 s)          for s <= 1/2   (lift, 0 -> h)
                                z(t) = h b(2 - 2 s)      for s >= 1/2   (lower, h -> 0)

so position, velocity and acceleration are continuous (the two height quintics meet at the apex
s = 1/2 with z = h, z' = z'' = 0; the height's jerk reverses there), the apex height is exactly
h at mid-swing, and the foot leaves and touches the ground with zero velocity and zero
acceleration in all three axes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


def wrap_angle(angle_rad):
    """angle_rad (a float or an array) wrapped to [-pi, pi)."""
    return (angle_rad + math.pi) % (2.0 * math.pi) - math.pi


def quintic_blend(s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(b, db/ds, d2b/ds2) of b(s) = 10 s^3 - 15 s^4 + 6 s^5, s clipped to [0, 1]."""
    s = np.clip(np.asarray(s, dtype=float), 0.0, 1.0)
    s2 = s * s
    value = s2 * s * (10.0 + s * (-15.0 + 6.0 * s))
    first = 30.0 * s2 * (1.0 - s) ** 2
    second = 60.0 * s * (1.0 - s) * (1.0 - 2.0 * s)
    return value, first, second


@dataclass(frozen=True)
class SwingFootTrajectory:
    """One swing: from (x, y, yaw) at lift-off to (x, y, yaw) at touchdown in duration_s,
    rising height_m above the ground at mid-swing (positions [m], yaw [rad])."""

    start_xy_m: tuple[float, float]
    end_xy_m: tuple[float, float]
    start_yaw_rad: float
    end_yaw_rad: float
    height_m: float
    duration_s: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.duration_s) and self.duration_s > 0):
            raise ValueError(f"duration_s must be finite and > 0, got {self.duration_s}")
        if not (math.isfinite(self.height_m) and self.height_m >= 0):
            raise ValueError(f"height_m must be finite and >= 0, got {self.height_m}")

    def evaluate(self, time_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(pose, velocity, acceleration), each (n, 4) with columns x, y, z (height above the
        ground) [m] and yaw [rad] (and their first and second time derivatives), at times
        time_s (n,) since lift-off, clipped to [0, duration_s]."""
        t = np.atleast_1d(np.asarray(time_s, dtype=float))
        T = self.duration_s
        s = np.clip(t / T, 0.0, 1.0)
        b, db, ddb = quintic_blend(s)
        delta = np.array(
            [
                self.end_xy_m[0] - self.start_xy_m[0],
                self.end_xy_m[1] - self.start_xy_m[1],
                wrap_angle(self.end_yaw_rad - self.start_yaw_rad),  # the short way round
            ]
        )
        start = np.array([self.start_xy_m[0], self.start_xy_m[1], self.start_yaw_rad])
        pose = np.empty((t.size, 4))
        vel = np.empty((t.size, 4))
        acc = np.empty((t.size, 4))
        pose[:, [0, 1, 3]] = start + np.outer(b, delta)
        vel[:, [0, 1, 3]] = np.outer(db / T, delta)
        acc[:, [0, 1, 3]] = np.outer(ddb / T**2, delta)
        # Height: lift on the first half, mirror image on the second (u = 2 s or 2 - 2 s).
        rising = s <= 0.5
        u = np.where(rising, 2.0 * s, 2.0 - 2.0 * s)
        hb, hdb, hddb = quintic_blend(u)
        du_dt = np.where(rising, 2.0 / T, -2.0 / T)
        pose[:, 2] = self.height_m * hb
        vel[:, 2] = self.height_m * hdb * du_dt
        acc[:, 2] = self.height_m * hddb * (2.0 / T) ** 2
        return pose, vel, acc
