"""Composition of the command, Kim et al., ICRA 2018, (25), in three readings.

(25) u(tk) = uc(tk) + d_hat(tk) + ug(tk) = uc(tk - dt) + int duc/dt dt + d_hat(tk) + ug(tk).

"The previous control input uc(tk - dt)" can be read two ways; both are implemented, named, and a
third, bounded variant of the lab's reading is added (`CompositionReading`):

"literal":      uc(k) = uc(k-1) + duc(k);            u(k) = uc(k) + d_hat(k) + ug(k)
                uc integrates only the LQR increments; the DOB term is added afresh each tick.
"accumulated":  u(k) - ug(k) = [u(k-1) - ug(k-1)] + duc(k) + d_hat(k)
                the lab's code: the previous TOTAL LQR+DOB output is the base, so the DOB term
                Kdist q(k) is summed tick by tick as well. The reproduction's default.
"accumulated-integral":
                as "accumulated", plus the DOB estimate's own integral with the servo's
                velocity-loop integral time Ti_d (`dob_integral_time_s`):
                I(k) = I(k-1) + (dt / Ti_d) Kdist q(k)
                u(k) - ug(k) = [u(k-1) - ug(k-1)] + duc(k) + Kdist q(k) + I(k)

All keep u = uc + d_hat + ug for the log: in the accumulated readings the logged d_hat is the
running sum of the DOB terms (and of I). ug is never accumulated: it is this tick's
feed-forward (8).

Anti-windup: the supervisor may clip or rate-limit the goal. `notify_applied(a)` moves the
difference a - u into uc, so the next tick starts from what was really sent (and the DOB, which
compares against the sent goal, stays consistent).

Statics with the paper's nominal servo (derived here, tested in
tests/controller/test_composition.py). Servo theta_dot_m = Kp (u + d - theta_m) with a constant
input disturbance d, constant reference and ug, LQR duc = -(Ke e + Kx dx), DOB q -> d. At rest
dx = 0, so duc = -Ke e, and:
- "literal": uc is constant only if Ke e = 0, so e = 0: the LQR's integral action removes any
  static yield; the link holds the reference for every Kdist (zero static compliance; against an
  obstacle the command keeps integrating the error until something saturates).
- "accumulated": u is constant only if duc + Kdist d = 0, so e = Ke^-1 Kdist d: the link yields in
  proportion to Kdist over the LQR's error gain per tick. This is the paper's "steady-state error
  grows with Kdist" (Fig. 6).
- "accumulated-integral": against this servo (no integral action) q stays d, I ramps and u has no
  rest state: the reading is for a servo WITH integral action (below). Do not use it otherwise.
- Without the LQR (uc held), "literal" gives (18): theta_m = uc + ug + (1 + Kdist) d, while
  "accumulated" has no rest state: u ramps by Kdist d per tick.

A real position servo integrates (the H54's velocity loop: torque = kv (Kpp (u - theta_m) -
dtheta_m) + I_s, dI_s/dt = (kv / Ti_s)(Kpp (u - theta_m) - dtheta_m)). Its static stiffness
k_s = Kpp kv holds a load tau with a lag tau / k_s that the integral winds out over Ti_s. The DOB
sees a load only through that lag: q ~ theta_m + dtheta_m / Kp - u = -(tau - I_s) / k_s when the
nominal Kp equals the servo's Kpp. Quasi-statically (the LQR balance Ke e = Kdist q is fast):
- "accumulated", free link: e(t) = Kdist (I_s(t) - tau) / (k_s Ke) decays as exp(-t / Ti_s)
  (exactly Ti_s in this limit, whatever Kdist and Ke); the equilibrium error is ZERO for every
  Kdist. Against a block (link fixed, e = e_b) the balance needs a lag Ke e_b / Kdist, the
  integral keeps growing on it, and the contact force creeps at k_s Ke e_b / (Kdist Ti_s L) per
  second (1.6 N/s at Kdist 1 on the testbed) until the actuator's overload trips.
- "accumulated-integral": dI_s/dt = -(k_s / Ti_s) q and dI/dt = (Kdist / Ti_d) q, so
  I_s + k_s (Ti_d / Ti_s) I / Kdist is conserved (= I_s at reset, where I = 0). At rest q = 0,
  so the balance reads Ke e = I, and
      contact (e = e_b):  servo torque = I_s(reset) - (Ti_d / Ti_s) k_s Ke e_b / Kdist
                          force on the block F L = tau_g(theta_b) - servo torque
      free link:          e = -Kdist (tau_g - I_s(reset)) / ((Ti_d / Ti_s) k_s Ke)
  With Ti_d = Ti_s the DOB's q + I / Kdist is the servo's whole torque over k_s, the force is
  constant from contact on (33 N on the testbed at Kdist 1, no creep, no trip) and the free
  link keeps the lab's quasi-static sag as its equilibrium. (F L - tau_g + I_s(0)) |e_free| =
  e_b (tau_g - I_s(0)) whatever Ti_d: softer contact costs a larger sag. Derivation and
  figures: docs/reproduction.md.

Robustness (tests/controller/test_closed_loop.py, `SampledLoop` with the paper's first-order
servo). Summing the DOB term makes it an integrator in a positive-feedback loop through the
servo's model error. For the DOB alone, a ramp in u meets a true servo (b') lagging less than
the nominal one (b) and feeds itself when Kdist (1/b - 1/b') >= 1: at Kdist = 1 a servo only 5 %
faster than the nominal Kp. With the LQR's integral action, at Kdist = 1 the loop tolerates a
true servo gain at most this much above the nominal Kp (K, D at nominal):
    I_link [kg m^2]                    0.05    0.25    0.376   1.25
    ZOH design and inverse model       +22 %   +27 %   +33 %   2.4x
    the lab's Euler design and Pn^-1   -       +13 %   +20 %   2.2x
(0.376 kg m^2 with Euler is the testbed's running configuration; the emulated servo is slower
than nominal, a first-order fit gives 7.2 1/s, so it runs stable.)
"literal" keeps the paper's |Kdist Q Delta| < 1 and holds +-30 % on K, D, Kp at Kdist = 1.
"""

from __future__ import annotations

import enum

import numpy as np


class CompositionReading(enum.StrEnum):
    """The reading of the paper's (25) (see the module docstring)."""

    ACCUMULATED = "accumulated"
    LITERAL = "literal"
    ACCUMULATED_INTEGRAL = "accumulated-integral"


COMPOSITION_READINGS: tuple[str, ...] = tuple(member.value for member in CompositionReading)


class Composition:
    """Holds uc, d_hat, ug and u for n joints; `reading` selects how the DOB term enters.

    dob_integral_gain_per_tick: dt / Ti_d for "accumulated-integral" (required there, refused
    otherwise). Arrays are owned by this object and overwritten every tick; copy them to keep
    them.
    """

    def __init__(
        self,
        n_joints: int,
        reading: CompositionReading,
        dob_integral_gain_per_tick: float | None = None,
    ) -> None:
        if reading not in COMPOSITION_READINGS:
            raise ValueError(f"composition must be one of {COMPOSITION_READINGS}, got {reading!r}")
        integrating = reading == CompositionReading.ACCUMULATED_INTEGRAL
        if integrating != (dob_integral_gain_per_tick is not None):
            raise ValueError(
                "the DOB integral gain is needed by the 'accumulated-integral' reading and "
                f"only by it (reading {reading!r}, gain {dob_integral_gain_per_tick})"
            )
        if dob_integral_gain_per_tick is not None and not (
            np.isfinite(dob_integral_gain_per_tick) and 0.0 < dob_integral_gain_per_tick <= 1.0
        ):
            raise ValueError(
                "the DOB integral gain per tick must be in (0, 1], got "
                f"{dob_integral_gain_per_tick}"
            )
        self.reading = reading
        self._accumulate_dob = reading != CompositionReading.LITERAL
        self._integral_gain = dob_integral_gain_per_tick or 0.0
        self.uc = np.zeros(n_joints)
        self.d_hat = np.zeros(n_joints)
        self.dob_integral = np.zeros(n_joints)
        self.ug = np.zeros(n_joints)
        self.u = np.zeros(n_joints)

    def reset(self, applied_command_rad: np.ndarray, gravity_input_rad: np.ndarray) -> None:
        """Bumpless start: the goal in force is `applied_command_rad`, no DOB term yet."""
        self.ug[:] = gravity_input_rad
        self.d_hat[:] = 0.0
        self.dob_integral[:] = 0.0
        np.subtract(applied_command_rad, self.ug, out=self.uc)
        self.u[:] = applied_command_rad

    def compose(
        self, lqr_increment: np.ndarray, dob_term: np.ndarray, gravity_input_rad: np.ndarray
    ) -> np.ndarray:
        """u(k) from duc(k), the DOB term Kdist q(k) and ug(k) per the reading."""
        self.uc += lqr_increment
        if self._accumulate_dob:
            self.d_hat += dob_term
            if self._integral_gain:
                self.dob_integral += self._integral_gain * dob_term
                self.d_hat += self.dob_integral
        else:
            self.d_hat[:] = dob_term
        self.ug[:] = gravity_input_rad
        np.add(self.uc, self.d_hat, out=self.u)
        self.u += self.ug
        return self.u

    def notify_applied(self, applied_command_rad: np.ndarray) -> None:
        """Anti-windup: uc absorbs (applied - computed), so u equals what was sent."""
        self.uc += applied_command_rad
        self.uc -= self.u
        self.u[:] = applied_command_rad
