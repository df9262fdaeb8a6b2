"""Composition of the command, Kim et al., ICRA 2018, (25), in its two readings.

(25) u(tk) = uc(tk) + d_hat(tk) + ug(tk) = uc(tk - dt) + int duc/dt dt + d_hat(tk) + ug(tk).

"The previous control input uc(tk - dt)" can be read two ways; both are implemented, named:

"literal":      uc(k) = uc(k-1) + duc(k);            u(k) = uc(k) + d_hat(k) + ug(k)
                uc integrates only the LQR increments; the DOB term is added afresh each tick.
"accumulated":  u(k) - ug(k) = [u(k-1) - ug(k-1)] + duc(k) + d_hat(k)
                the lab's code (reference note sec. 1): the previous TOTAL LQR+DOB output is
                the base, so the DOB term is summed tick by tick as well.

Both keep u = uc + d_hat + ug for the log: in "accumulated" the logged d_hat is the running sum
of the DOB terms. ug is never accumulated: it is the feed-forward of this tick (8).

Anti-windup: the supervisor may clip or rate-limit the goal. `notify_applied(a)` moves the
difference a - u into uc, so the next tick starts from what was really sent (and the DOB, which
compares against the sent goal, stays consistent).

Statics (derived here, tested in tests/test_controller_composition.py). Nominal servo with a
constant input disturbance d (theta_dot_m = Kp (u + d - theta_m)), constant reference and ug,
LQR duc = -(Ke e + Kx dx), DOB d_hat -> Kdist d. At rest dx = 0, so duc = -Ke e, and:
- "literal": uc is constant only if Ke e = 0, so e = 0: the LQR's integral action removes any
  static yield; the link holds the reference for every Kdist (zero static compliance; against an
  obstacle the command keeps integrating the error until something saturates).
- "accumulated": u is constant only if duc + Kdist d = 0, so e = Ke^-1 Kdist d: the link yields in
  proportion to Kdist over the LQR's error gain per tick; the force against an obstacle stays
  bounded. This is the paper's "steady-state error grows with Kdist" (Fig. 6).
- Without the LQR (uc held), "literal" gives (18): theta_m = uc + ug + (1 + Kdist) d, while
  "accumulated" has no rest state: u ramps by Kdist d per tick.

Stability (tests/test_controller_closed_loop.py). Summing the DOB term makes it an integrator
in a positive-feedback loop through the servo's model error. For the DOB alone, a ramp in u
meets a true servo (b') lagging less than the nominal one (b) and feeds itself when
Kdist (1/b - 1/b') >= 1: at Kdist = 1 a servo only 5 % faster than the nominal Kp. The LQR's
integral action widens this to about 22 % (light links, 0.05 kg m^2) or 2.2x (1.25 kg m^2).
"literal" keeps the paper's |Kdist Q Delta| < 1 and holds +-30 % on K, D, Kp at Kdist = 1.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

CompositionReading = Literal["accumulated", "literal"]
COMPOSITION_READINGS: tuple[str, ...] = ("accumulated", "literal")


class Composition:
    """Holds uc, d_hat, ug and u for n joints; `reading` selects how the DOB term enters.

    Arrays are owned by this object and overwritten every tick; copy them to keep them.
    """

    def __init__(self, n_joints: int, reading: CompositionReading) -> None:
        if reading not in COMPOSITION_READINGS:
            raise ValueError(f"composition must be one of {COMPOSITION_READINGS}, got {reading!r}")
        self.reading = reading
        self._accumulate_dob = reading == "accumulated"
        self.uc = np.zeros(n_joints)
        self.d_hat = np.zeros(n_joints)
        self.ug = np.zeros(n_joints)
        self.u = np.zeros(n_joints)

    def reset(self, applied_command_rad: np.ndarray, gravity_input_rad: np.ndarray) -> None:
        """Bumpless start: the goal in force is `applied_command_rad`, no DOB term yet."""
        self.ug[:] = gravity_input_rad
        self.d_hat[:] = 0.0
        np.subtract(applied_command_rad, self.ug, out=self.uc)
        self.u[:] = applied_command_rad

    def compose(
        self, lqr_increment: np.ndarray, dob_term: np.ndarray, gravity_input_rad: np.ndarray
    ) -> np.ndarray:
        """u(k) from duc(k), d_hat(k) = Kdist q(k) and ug(k) per the reading."""
        self.uc += lqr_increment
        if self._accumulate_dob:
            self.d_hat += dob_term
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
