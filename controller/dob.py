"""Disturbance-observer based estimator, Kim et al., ICRA 2018, Sec. III-B, (9)-(18).

Continuous form, per joint:

    (9)  theta_m = P(s) (u' + d)                 real servo, input disturbance d [rad]
    (10) u' = uc + d_hat                         (plus the gravity input, see below)
    (11) d_hat = Kdist Q(s) (Pn^-1(s) theta_m - u')
         Pn(s) = Kp / (s + Kp) (nominal servo (4)),  Q(s) = wc / (s + wc) (first-order low pass)

With P = Pn, (11) gives d_hat = Kdist Q(s) d, and theta_m = P(s) (uc + (1 + Kdist Q(s)) d)
(18): the static motor angle yields to a constant disturbance by (1 + Kdist) d. Kdist > 0
makes the joint comply; Kdist < 0 makes it push against the disturbance.

Discrete form, at the loop period dt (what runs; exact for the sampled nominal servo):

    nominal servo sampled: theta_m(k+1) = a theta_m(k) + b u(k)
        "zoh":   a = exp(-Kp dt), b = 1 - a   (exact for a goal held over the tick; default)
        "euler": a = 1 - Kp dt,   b = Kp dt   (the lab's code; 0.95 / 0.05 at Kp = 10, 200 Hz)
    inverse nominal model:  u_hat(k-1) = (theta_m(k) - a theta_m(k-1)) / b
    raw estimate:           raw(k) = u_hat(k-1) - u_sent(k-1)
    Q filter:               q(k) = alpha q(k-1) + (1 - alpha) raw(k),  alpha = exp(-2 pi fc dt)
    output:                 d_hat(k) = Kdist q(k)

With the sampled nominal servo and a disturbance held over each tick, raw(k) = d(k-1) exactly, so
d -> d_hat is Kdist (1 - alpha) / (z - alpha): the zero-order-hold equivalent of Kdist Q(s)
(pole matching alpha = exp(-wc dt) is exactly that equivalent: the filter's response to a held
step is 1 - exp(-wc k dt), the continuous step response at the ticks).

The filter pole, said once. The lab's filter is q(k) = 0.7 q(k-1) + 0.3 raw(k) at 200 Hz
(`LAB_Q_FILTER_POLE`), i.e. fc = -ln(0.7) / (2 pi 0.005 s) = 11.3533 Hz under this mapping
(`LAB_DOB_CUTOFF_HZ`, the default of `ControllerParams`). A cut-off rounded to 11.4 Hz (the
testbed configuration's) gives alpha = exp(-2 pi 11.4 0.005) = 0.69897, not 0.7: the lab's values
are reached exactly with the cut-off `LAB_DOB_CUTOFF_HZ` or by giving the pole itself
(`filter_pole=0.7`, `ControllerParams(dob_filter_pole=0.7)`).

Kdist changes ramp (the humanoid switches Kdist by walking phase: 0.2 in stance, 1.0 on the
landing leg). `set_kdist` does not step the gain: it moves along the lab's cubic with zero slope
at both ends over `kdist_ramp_ticks` updates (`CubicRamp`; the lab: 20 ticks = 0.1 s at 200 Hz).
What the ramp bounds depends on the reading of (25) (`controller.composition`): in "literal"
the goal carries Kdist q, so a step in Kdist would step the goal by dKdist q, and the ramp limits
the goal's increment to 1.5 |dKdist q| / N per tick; in the accumulated readings the goal is a
sum of Kdist q, so a step in Kdist steps the goal's RATE by dKdist q per tick, and the ramp limits
the change of the per-tick increment to 1.5 |dKdist q| / N.

Which command the DOB compares against: u_sent, the whole goal actually written to the servo at
the previous tick, gravity input ug included and after any clipping by the supervisor. Pn^-1
theta_m reconstructs what the servo was driven with; subtracting anything less than what was
sent would report the rest (e.g. ug) as a disturbance. The lab's code compared against the LQR+DOB
output without its gravity offset, so its DOB reported the offset itself as a disturbance; with
the accumulated reading of (25) that undoes the gravity feed-forward until the LQR balances it
(a static link error of Kdist ug / error_gain). See `controller.composition`.

Kdist is applied after the filter, per joint, and a Kdist change keeps the filter state: the
output changes by exactly (Kdist(k) - Kdist(k-1)) q(k) at each tick of the ramp, nothing else.

Noise, for a motor encoder of quantum q_m [rad] (the caller passes it; for the testbed's H54,
2 pi / 501,923 = 1.25e-5 rad): the quantisation error enters raw(k) as (eps(k) - a eps(k-1)) / b
with eps white, uniform over a quantum (variance q_m^2 / 12): rms q_m sqrt((1 + a^2) / 12) / b
(1.0e-4 rad for that q_m at Kp = 10, 200 Hz, ZOH). After Q:
rms q_m (1 - alpha) sqrt((1 + (alpha - a)^2 / (1 - alpha^2)) / 12) / b (2.4e-5 rad;
`quantisation_noise_rms_rad`); for scale, 1 N m on a servo of 2000 N m/rad stiffness is 5e-4 rad.
"""

from __future__ import annotations

import math

import numpy as np

from controller.model import DISCRETISATIONS, Discretisation

# d(k) = 0.7 d(k-1) + 0.3 raw(k): the lab's code (psh117/dyros_jet, walking_controller.cpp)
LAB_Q_FILTER_POLE = 0.7
LAB_LOOP_PERIOD_S = 1.0 / 200.0


def q_filter_pole(cutoff_hz: float, dt_s: float) -> float:
    """alpha = exp(-2 pi fc dt): the discrete pole of Q(s) = wc / (s + wc) (ZOH equivalent)."""
    if not (np.isfinite(cutoff_hz) and cutoff_hz > 0):
        raise ValueError(f"DOB cut-off must be finite and > 0 Hz, got {cutoff_hz}")
    if not (np.isfinite(dt_s) and dt_s > 0):
        raise ValueError(f"dt_s must be finite and > 0, got {dt_s}")
    return math.exp(-2.0 * math.pi * cutoff_hz * dt_s)


def q_filter_cutoff_hz(pole: float, dt_s: float) -> float:
    """Inverse of `q_filter_pole`: fc = -ln(alpha) / (2 pi dt) (alpha = 0: no filter, inf)."""
    if not 0.0 <= pole < 1.0:
        raise ValueError(f"filter pole must be in [0, 1), got {pole}")
    return math.inf if pole == 0.0 else -math.log(pole) / (2.0 * math.pi * dt_s)


LAB_DOB_CUTOFF_HZ = q_filter_cutoff_hz(LAB_Q_FILTER_POLE, LAB_LOOP_PERIOD_S)  # 11.35 Hz


def resolve_q_filter_pole(cutoff_hz: float | None, filter_pole: float | None, dt_s: float) -> float:
    """The Q-filter pole from exactly one of a cut-off [Hz] or the pole itself."""
    if (cutoff_hz is None) == (filter_pole is None):
        raise ValueError("give the DOB filter either a cut-off in Hz or its pole, not both/neither")
    if filter_pole is not None:
        if not (np.isfinite(filter_pole) and 0.0 <= filter_pole < 1.0):
            raise ValueError(f"the DOB filter pole must be in [0, 1), got {filter_pole}")
        return float(filter_pole)
    assert cutoff_hz is not None
    return q_filter_pole(cutoff_hz, dt_s)


class CubicRamp:
    """Per-joint values that move to a new target along the lab's cubic (zero slope at both
    ends) over `ticks` calls of `advance()`, from the value x0 they had when the target was set:

        x(i) = x0 + (x1 - x0) (3 s^2 - 2 s^3),  s = i / N,  i = 1 .. N;  x(N) = x1 exactly.

    The largest step |x(i) - x(i-1)| is at most 1.5 |x1 - x0| / N (the cubic's slope at
    s = 1/2). N = 0: the target is taken at the next `advance()` (a step). A new target during a
    ramp starts a new ramp from the present value.
    """

    def __init__(self, initial: np.ndarray, ticks: int) -> None:
        if not (isinstance(ticks, int | np.integer) and ticks >= 0):
            raise ValueError(f"the ramp length must be a whole number of ticks >= 0, got {ticks}")
        self.ticks = int(ticks)
        self._value = np.array(initial, dtype=float)
        self._start = self._value.copy()
        self._target = self._value.copy()
        self._step = max(self.ticks, 1)  # at rest: nothing to do

    @property
    def value(self) -> np.ndarray:
        return self._value

    @property
    def target(self) -> np.ndarray:
        return self._target.copy()

    def set_target(self, target: np.ndarray) -> None:
        self._start[:] = self._value
        self._target[:] = target
        self._step = 0

    def advance(self) -> np.ndarray:
        """One tick along the ramp; returns the value for this tick."""
        if self._step >= max(self.ticks, 1):
            return self._value
        self._step += 1
        if self._step >= self.ticks:
            self._value[:] = self._target
        else:
            s = self._step / self.ticks
            self._value[:] = self._start + (self._target - self._start) * (3 * s * s - 2 * s**3)
        return self._value


def nominal_servo_coefficients(
    servo_gain_per_s: np.ndarray, dt_s: float, method: Discretisation = "zoh"
) -> tuple[np.ndarray, np.ndarray]:
    """(a, b) of the sampled nominal servo theta_m(k+1) = a theta_m(k) + b u(k), per joint."""
    gain = np.asarray(servo_gain_per_s, dtype=float)
    if method == Discretisation.ZOH:
        a = np.exp(-gain * dt_s)
        return a, 1.0 - a
    if method == Discretisation.EULER:
        return 1.0 - gain * dt_s, gain * dt_s
    raise ValueError(f"discretisation must be one of {DISCRETISATIONS}, got {method!r}")


def quantisation_noise_rms_rad(
    resolution_rad: float,
    servo_gain_per_s: float,
    cutoff_hz: float,
    dt_s: float,
    method: Discretisation = "zoh",
) -> float:
    """Rms of q(k) caused by motor-angle quantisation (white, uniform errors; see above)."""
    a, b = nominal_servo_coefficients(np.array(servo_gain_per_s), dt_s, method)
    alpha = q_filter_pole(cutoff_hz, dt_s)
    shape = 1.0 + (alpha - float(a)) ** 2 / (1.0 - alpha**2)
    return resolution_rad * (1.0 - alpha) * math.sqrt(shape / 12.0) / float(b)


def discrete_q_response(frequency_hz: np.ndarray, cutoff_hz: float, dt_s: float) -> np.ndarray:
    """(1 - alpha) / (z - alpha) at z = exp(j 2 pi f dt): what d -> d_hat / Kdist should be."""
    alpha = q_filter_pole(cutoff_hz, dt_s)
    z = np.exp(1j * 2.0 * np.pi * np.asarray(frequency_hz, dtype=float) * dt_s)
    return (1.0 - alpha) / (z - alpha)


class DisturbanceObserver:
    """The discrete DOB of (9)-(11) for n joints (see the module docstring for the equations).

    Per tick: `update(theta_m(k), u_sent(k-1))` returns d_hat(k) = Kdist(k) q(k). The returned
    array is owned by the observer and overwritten by the next update.

    cutoff_hz or filter_pole (exactly one): the Q filter; kdist: the initial gain (taken at
    once); kdist_ramp_ticks: how many updates a later `set_kdist` takes (0: a step).
    """

    def __init__(
        self,
        servo_gain_per_s: np.ndarray,
        cutoff_hz: float | None,
        dt_s: float,
        kdist: np.ndarray | float,
        method: Discretisation = "zoh",
        *,
        filter_pole: float | None = None,
        kdist_ramp_ticks: int = 0,
    ) -> None:
        servo_gain = np.array(servo_gain_per_s, dtype=float, ndmin=1)
        if servo_gain.ndim != 1 or np.any(~np.isfinite(servo_gain)) or np.any(servo_gain <= 0):
            raise ValueError(
                f"servo_gain_per_s must be a 1-D array of values > 0, got {servo_gain}"
            )
        if not (np.isfinite(dt_s) and dt_s > 0):
            raise ValueError(f"dt_s must be finite and > 0, got {dt_s}")
        self.n_joints = servo_gain.size
        self.dt_s = float(dt_s)
        self.method = method
        self._alpha = resolve_q_filter_pole(cutoff_hz, filter_pole, dt_s)
        self.cutoff_hz = q_filter_cutoff_hz(self._alpha, dt_s)
        self._a, self._b = nominal_servo_coefficients(servo_gain, dt_s, method)
        self._kdist = CubicRamp(self._checked_kdist(kdist), kdist_ramp_ticks)
        self._previous_motor_angle = np.zeros(self.n_joints)
        self._filtered = np.zeros(self.n_joints)
        self._raw = np.zeros(self.n_joints)
        self._output = np.zeros(self.n_joints)
        self._resynced = False

    @property
    def kdist(self) -> np.ndarray:
        """The gain of the last update (during a ramp: the ramp's present value)."""
        return self._kdist.value.copy()

    @property
    def kdist_target(self) -> np.ndarray:
        return self._kdist.target

    @property
    def filter_pole(self) -> float:
        return self._alpha

    @property
    def filtered_estimate_rad(self) -> np.ndarray:
        """q(k): the Q-filtered disturbance estimate before Kdist [rad of servo input]."""
        return self._filtered.copy()

    def set_kdist(self, kdist: np.ndarray | float) -> None:
        """New Kdist per joint (scalar = all joints): ramps from the next update on (see
        `CubicRamp`), reaching it exactly at the kdist_ramp_ticks-th update."""
        self._kdist.set_target(self._checked_kdist(kdist))

    def _checked_kdist(self, kdist: np.ndarray | float) -> np.ndarray:
        values = np.array(kdist, dtype=float, ndmin=1)
        if values.size == 1:
            values = np.full(self.n_joints, values[0])
        if values.shape != (self.n_joints,):
            raise ValueError(
                f"kdist needs {self.n_joints} entries (one per joint), got {values.size}"
            )
        if not np.all(np.isfinite(values)):
            raise ValueError(f"kdist must be finite, got {values}")
        return values

    def reset(self, motor_angle_rad: np.ndarray) -> None:
        """Start with no disturbance, the servo at rest at `motor_angle_rad`."""
        self._previous_motor_angle[:] = motor_angle_rad
        self._filtered[:] = 0.0
        self._output[:] = 0.0
        self._resynced = False

    def resync(self) -> None:
        """After a gap in the samples (a skipped tick, a failed read): the inverse nominal model
        (10) needs theta_m one period apart, which the next sample does not have. Its update
        then only restarts the difference from that sample and holds the filtered estimate."""
        self._resynced = True

    def update(self, motor_angle_rad: np.ndarray, sent_command_rad: np.ndarray) -> np.ndarray:
        """d_hat(k) from theta_m(k) and the goal sent at the previous tick, u_sent(k-1)."""
        kdist = self._kdist.advance()
        if self._resynced:
            self._resynced = False
            self._previous_motor_angle[:] = motor_angle_rad
            np.multiply(kdist, self._filtered, out=self._output)
            return self._output
        raw = self._raw
        # u_hat(k-1) = (theta_m(k) - a theta_m(k-1)) / b, then raw = u_hat - u_sent.
        np.multiply(self._a, self._previous_motor_angle, out=raw)
        np.subtract(motor_angle_rad, raw, out=raw)
        raw /= self._b
        raw -= sent_command_rad
        self._filtered *= self._alpha
        self._filtered += (1.0 - self._alpha) * raw
        self._previous_motor_angle[:] = motor_angle_rad
        np.multiply(kdist, self._filtered, out=self._output)
        return self._output
