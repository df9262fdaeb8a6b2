"""The identification excitation: a rate-limited logarithmic chirp on the goal, link free.

Signal (goal = hold_goal + offset(t), written once a tick and held, as the loop does):

    settle | fit sweep f0 -> f1 | validation sweep f1 -> f0 | settle
    offset(t) = a(t) sin(phi(t)),   omega(t) = dphi/dt = omega0 exp(c t),
    c = ln(omega1/omega0) / T_sweep,
    a(t) = min(A, s r / omega(t)) * taper(t)

A is the amplitude, r the goal-rate limit, s < 1 a margin for the envelope's own slope, taper a
raised-cosine ramp at both ends of each sweep. The holds at both ends let the servo's weak
integral action wind the gravity lag out where the fit can see it (that is what identifies the
velocity-loop integral time), and the second, shorter sweep covers the same band again so it
can be held out of the fit and used to measure how well the model predicts.

Why this band (for the H54 testbed and the paper's constants; the defaults cover both ends):
- the servo's position loop, Kp ~ 10 rad/s (1.6 Hz), is seen as the goal-to-motor lag: the
  sweep starts a decade below it (0.2 Hz) and passes it;
- the gear: the link follows the motor through I s^2 + D s + K, whose deflection
  delta = -I s^2 / (I s^2 + D s + K) theta_m is set by K below K/D (~20 rad/s, 3.2 Hz) and by D
  above it. The sweep runs to 10 Hz (63 rad/s), three times K/D, so that both are seen;
- the velocity loop (kv/Jm ~ 300 rad/s, ~50 Hz) is not excited directly (a goal rate limit of
  ~2 rad/s leaves no amplitude there); its gain shows in the current the servo draws for a
  given position and velocity error, which the fit uses instead.
A PRBS would excite the band more evenly, but its steps break the goal-rate limit; limited to
r, its edges become ramps of length 2A/r, which low-passes it at about r/(pi A), below the band
that identifies D. A rate-limited chirp puts the allowed rate where it is needed.

Amplitude and rate are bounded by construction and checked on the sampled goal; the current
this draws is bounded by `peak_motor_torque_bound_nm` (compare it with the overload threshold).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

# The envelope keeps a(t) omega(t) <= s r; the rest of the rate budget is for da/dt.
_RATE_MARGIN = 0.85


@dataclass(frozen=True)
class ChirpExcitation:
    """Parameters of the identification chirp (all SI; angles are link angles).

    holding_angle_rad: link angle the excitation swings around (the experiment homes there).
    amplitude_rad: largest goal excursion from the hold, A.
    start_frequency_hz, stop_frequency_hz: the swept band f0 -> f1.
    fit_sweep_duration_s: the up-sweep the fit uses; validation_sweep_duration_s: the down-sweep
      held out of the fit (0: none).
    settle_duration_s: holds before, between the sweeps none, and after.
    taper_duration_s: raised-cosine fade in/out of each sweep.
    max_goal_rate_rad_s: the goal never moves faster than this (keep it below the supervisor's
      max_goal_rate_rad_s, or the supervisor rewrites the excitation).
    min_angle_rad, max_angle_rad: position limits of the joint.
    period_s: the loop period (the goal is held over each).
    """

    holding_angle_rad: float = 0.0
    amplitude_rad: float = 0.1
    start_frequency_hz: float = 0.2
    stop_frequency_hz: float = 10.0
    fit_sweep_duration_s: float = 30.0
    validation_sweep_duration_s: float = 12.0
    settle_duration_s: float = 2.0
    taper_duration_s: float = 1.0
    max_goal_rate_rad_s: float = 1.6
    min_angle_rad: float = -0.8
    max_angle_rad: float = 0.8
    period_s: float = 0.005

    def __post_init__(self) -> None:
        for name in (
            "amplitude_rad",
            "start_frequency_hz",
            "fit_sweep_duration_s",
            "max_goal_rate_rad_s",
            "period_s",
        ):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"excitation {name} must be finite and > 0, got {value}")
        for name in ("validation_sweep_duration_s", "settle_duration_s", "taper_duration_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"excitation {name} must be finite and >= 0, got {value}")
        if not self.stop_frequency_hz > self.start_frequency_hz:
            raise ValueError("excitation stop_frequency_hz must exceed start_frequency_hz")
        nyquist_hz = 0.5 / self.period_s
        if self.stop_frequency_hz > 0.25 * nyquist_hz:
            raise ValueError(
                f"excitation stop_frequency_hz {self.stop_frequency_hz} Hz is above a quarter of "
                f"the loop's Nyquist frequency ({nyquist_hz:g} Hz): the held goal would not "
                "resemble the chirp"
            )
        shortest = min(
            self.fit_sweep_duration_s,
            self.validation_sweep_duration_s or self.fit_sweep_duration_s,
        )
        if 2 * self.taper_duration_s > shortest:
            raise ValueError("excitation taper_duration_s must be at most half of each sweep")
        low = self.holding_angle_rad - self.amplitude_rad
        high = self.holding_angle_rad + self.amplitude_rad
        if low < self.min_angle_rad or high > self.max_angle_rad:
            raise ValueError(
                f"excitation swings the link over [{low:.3f}, {high:.3f}] rad, outside the "
                f"position limits [{self.min_angle_rad}, {self.max_angle_rad}] rad"
            )

    @property
    def duration_s(self) -> float:
        return (
            2 * self.settle_duration_s
            + self.fit_sweep_duration_s
            + self.validation_sweep_duration_s
        )

    @property
    def validation_start_s(self) -> float:
        """Time from the excitation's start at which the held-out part begins."""
        return self.settle_duration_s + self.fit_sweep_duration_s

    @property
    def holdout_fraction(self) -> float:
        """Share of the excitation after `validation_start_s` (validation sweep + last hold)."""
        return 1.0 - self.validation_start_s / self.duration_s


@dataclass(frozen=True)
class ExcitationTrajectory:
    """The sampled goal offsets: goal_rad[k] = hold_goal + goal_offset_rad[k] over tick k."""

    time_s: np.ndarray
    goal_offset_rad: np.ndarray
    validation_start_s: float


def _sweep(
    time_s: np.ndarray, duration_s: float, f_from_hz: float, f_to_hz: float, p: ChirpExcitation
) -> np.ndarray:
    """One logarithmic sweep from f_from to f_to over [0, duration_s), rate-limited envelope."""
    w_from, w_to = 2 * math.pi * f_from_hz, 2 * math.pi * f_to_hz
    rate = math.log(w_to / w_from) / duration_s
    omega = w_from * np.exp(rate * time_s)
    phase = w_from * np.expm1(rate * time_s) / rate
    envelope = np.minimum(p.amplitude_rad, _RATE_MARGIN * p.max_goal_rate_rad_s / omega)
    if p.taper_duration_s > 0:
        ramp_in = np.clip(time_s / p.taper_duration_s, 0.0, 1.0)
        ramp_out = np.clip((duration_s - time_s) / p.taper_duration_s, 0.0, 1.0)
        envelope = envelope * 0.5 * (1 - np.cos(np.pi * np.minimum(ramp_in, ramp_out)))
    return envelope * np.sin(phase)


def chirp_goal_offsets(p: ChirpExcitation) -> ExcitationTrajectory:
    """The excitation sampled at the loop period; raises if a limit would be broken.

    Checked on the samples (what the supervisor sees): |offset| <= A and
    |offset[k+1] - offset[k]| <= max_goal_rate_rad_s * period_s.
    """
    n = int(round(p.duration_s / p.period_s))
    time_s = np.arange(n) * p.period_s
    offset = np.zeros(n)
    start = p.settle_duration_s
    for duration, f_from, f_to in (
        (p.fit_sweep_duration_s, p.start_frequency_hz, p.stop_frequency_hz),
        (p.validation_sweep_duration_s, p.stop_frequency_hz, p.start_frequency_hz),
    ):
        if duration <= 0:
            continue
        inside = (time_s >= start) & (time_s < start + duration)
        offset[inside] = _sweep(time_s[inside] - start, duration, f_from, f_to, p)
        start += duration
    steps = np.abs(np.diff(offset, prepend=0.0, append=0.0))
    rate = float(steps.max()) / p.period_s
    if rate > p.max_goal_rate_rad_s:
        raise ValueError(
            f"the sampled chirp moves the goal at up to {rate:.3f} rad/s, above the limit "
            f"{p.max_goal_rate_rad_s} rad/s: lengthen taper_duration_s or the sweeps"
        )
    if float(np.abs(offset).max()) > p.amplitude_rad * (1 + 1e-12):
        raise AssertionError("chirp envelope exceeded its amplitude")  # construction bug
    return ExcitationTrajectory(time_s, offset, p.validation_start_s)


def peak_motor_torque_bound_nm(
    p: ChirpExcitation,
    *,
    link_inertia_kg_m2: float,
    motor_inertia_kg_m2: float,
    gravity_moment_kg_m: float,
    position_gain_per_s: float,
    velocity_gain_nms_per_rad: float,
    coulomb_friction_nm: float,
    gravity_m_s2: float = 9.81,
) -> float:
    """A conservative bound on the motor torque the excitation draws (nominal figures).

        |tau_m| <= m g r + F_c + (J_m + I_link) * 2 Kp r + kv Kp r T

    - gravity at its worst (link horizontal) and the gearbox's Coulomb friction;
    - acceleration: the servo as the first-order lag (4) turns a goal moving at most at rate r
      into a motor velocity that is a lag of the goal's velocity, so |d2theta_m/dt2| =
      Kp |du/dt - dtheta_m/dt| <= 2 Kp r; the link, slower than the gear, moves with the motor;
    - the goal is held over each tick of length T: each new goal steps the velocity command by
      Kp r T and the velocity loop answers that step with kv times it before it settles.
    Divide by the torque constant for a current and compare with the overload threshold.
    """
    acceleration = 2 * position_gain_per_s * p.max_goal_rate_rad_s
    tick_step = velocity_gain_nms_per_rad * position_gain_per_s * p.max_goal_rate_rad_s * p.period_s
    return (
        gravity_m_s2 * gravity_moment_kg_m
        + coulomb_friction_nm
        + (motor_inertia_kg_m2 + link_inertia_kg_m2) * acceleration
        + tick_step
    )
