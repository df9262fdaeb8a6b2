"""A CoM stabiliser for a robot whose joints are springs (ours, beyond the 2018 paper).

The lab's CoM feedback (`lab_terms.CenterOfMassFeedback`) never closes a loop on the sway the
robot makes on its compliant joints: in its 2018 form the measured pelvis and the measured CoM
carry the same sway and it cancels; in its master form the pelvis is placed, not measured; and
as an integral of the whole CoM error it destabilises the sway. On one foot DYROS-JET's lateral
sway is a lightly damped mode of the joints' compliance against gravity (the commanded CoM c_u,
the real one c):

    c'' = w^2 (c_u - c),   w^2 = (k - m g h) / (m h^2)

(k the stance leg's roll stiffness, ~564 N m/rad per joint; on the emulated robot w ~ 4.4 rad/s,
damping ratio ~0.25; docs/walking.md): an integral I on the pelvis adds s^3 + 2 z w s^2 + w^2 s +
w^2 I, stable only for I < 2 z w ~ 2.2 1/s, where the lab's 0.15 per tick is 30 1/s. What a spring
needs is a proportional-derivative correction of the commanded CoM by the measured error e =
c_measured - c_planned (x, y):

    pelvis += -(gain e + damping_s e'),   e' low-passed at velocity_cutoff_hz

which makes the sway e'' + w^2 damping_s e' + w^2 (1 + gain) e = 0 in this model: its frequency
raised by (1 + gain)^0.5 and its damping ratio by w damping_s / (2 (1 + gain)^0.5) (0.16 at
gain 1, damping_s 0.1 s), through the servo's lag (1/Kpp = 0.1 s) in the real loop. It acts
through the legs' IK like the lab's feedback (`hil/experiments/walking_scheme.py`), capped at
max_correction_m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class CenterOfMassStabiliser:
    """The PD correction of the commanded pelvis (module docstring): gain [1], damping_s [s],
    velocity_cutoff_hz the error rate's low pass, max_correction_m the correction's bound."""

    gain: float = 1.0
    damping_s: float = 0.1
    velocity_cutoff_hz: float = 10.0
    max_correction_m: float = 0.05

    def __post_init__(self) -> None:
        for name in ("gain", "damping_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {value}")
        for name in ("velocity_cutoff_hz", "max_correction_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be finite and > 0, got {value}")

    def tracker(self, dt_s: float) -> StabiliserState:
        """A fresh state for one run at period dt_s."""
        return StabiliserState(self, dt_s)


class StabiliserState:
    """One run's stabiliser: the last error and its filtered rate."""

    def __init__(self, params: CenterOfMassStabiliser, dt_s: float) -> None:
        if not (math.isfinite(dt_s) and dt_s > 0):
            raise ValueError(f"dt_s must be finite and > 0, got {dt_s}")
        self.params = params
        self.dt_s = dt_s
        self._pole = math.exp(-2.0 * math.pi * params.velocity_cutoff_hz * dt_s)
        self._error: np.ndarray | None = None
        self.error_rate = np.zeros(2)

    def correction(self, measured_com_m: np.ndarray, planned_com_m: np.ndarray) -> np.ndarray:
        """-(gain e + damping_s e') (x, y) [m], capped; the first call sees no rate."""
        error = np.asarray(measured_com_m, dtype=float)[:2] - np.asarray(planned_com_m)[:2]
        if self._error is not None:
            rate = (error - self._error) / self.dt_s
            self.error_rate = self._pole * self.error_rate + (1.0 - self._pole) * rate
        self._error = error
        params = self.params
        correction = -(params.gain * error + params.damping_s * self.error_rate)
        length = float(np.hypot(*correction))
        if length > params.max_correction_m:
            correction *= params.max_correction_m / length
        return correction
