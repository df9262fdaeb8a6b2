"""The actuators' own overload protection, per model, and the software guard's rule derived from it.

The protection (what the actuator's firmware does, modelled as a timer):

    a timer runs up at 1 s/s while |I| >= fraction x the active current limit, back down at the
    same rate below it, never below 0; at trip_time_s the actuator raises its Overload bit and
    (default Shutdown mask) turns its torque off

    H54-200-S500-R   fraction 0.9, trip_time_s 1.5 s. ROBOTIS publish no threshold (e-Manual,
                     "Hardware Error Status": "Overload ... when a persistent load that exceeds
                     the maximum output is applied"). ASSUMPTION, the one the emulated firmware
                     makes (sim_backend/servo.py `H54ServoParams.overload_current_fraction`,
                     `overload_trip_time_s`; tests/hil/test_guard_rule.py holds the two equal):
                     a load held near the current cap for about a thermal time constant of
                     the drive trips it. On hardware, measure it (docs/safety.md says how).
    the other models of the family (docs/actuators.md)
                     the H54-200-S500-R's fraction and time, as the emulated firmware carries
                     them over (sim_backend/servo_models.py: ROBOTIS publish no threshold for
                     any model): an ASSUMPTION.

The guard's rule (`GuardRule`) is the same kind of timer: the guard's timer runs up while
|I| >= its fraction of the current limit and down below it, and the guard fires at its time.

    derived    ([safety] current_guard_margin_s set) the protection's own fraction and rate, so
               the guard's timer is the actuator's as the host samples it, and it fires the margin
               before the protection would trip: for any current, the actuator trips no earlier
               than `margin` after the guard (its timer needs that long to run from the guard's
               time to its own), and where the actuator's timer stays below trip_time - margin
               the guard does not act at all. The margin is the time the reaction needs to bring
               the current down with the timer running at full rate all along (a robot's figure:
               hil/data/*.toml say theirs, docs/safety.md why).
    explicit   (margin unset) `current_guard_fraction` and `current_guard_time_s` as given; with
               a fraction below the protection's and a time below its trip time every tick that
               runs the actuator's timer up runs the guard's up too, so it fires first (the
               testbed's 0.8 and 0.6 s: 0.97 s before the trip of Fig. 5's contact), but it also
               fires where the actuator would never trip.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from hil.config import Config, SafetySection


@dataclass(frozen=True)
class OverloadProtection:
    """One actuator model's overload protection (module docstring)."""

    model: str
    fraction: float  # of the active current limit
    trip_time_s: float
    source: str


H54_200_S500_R = OverloadProtection(
    "H54-200-S500-R",
    fraction=0.9,
    trip_time_s=1.5,
    source="assumption (ROBOTIS publish no threshold), as sim_backend/servo.py emulates it",
)
PROTECTIONS = {p.model: p for p in (H54_200_S500_R,)}
CARRIED_OVER = (
    "assumption: the H54-200-S500-R's fraction and time (ROBOTIS publish no threshold for any "
    "model), as sim_backend/servo_models.py emulates it"
)


def protection_of(model: str) -> OverloadProtection:
    """A model's protection: its own where one is modelled, else the H54-200-S500-R's carried
    over to any other model of the family the driver knows (module docstring)."""
    if model in PROTECTIONS:
        return PROTECTIONS[model]
    from drivers.dynamixel import model_number  # the family's names (ValueError otherwise)

    try:
        model_number(model)
    except ValueError:
        raise ValueError(
            f"no overload protection is modelled for actuator model {model!r}: it is not a "
            "model of the DYNAMIXEL PRO family (docs/actuators.md)"
        ) from None
    base = H54_200_S500_R
    return OverloadProtection(model, base.fraction, base.trip_time_s, CARRIED_OVER)


def protections_of(config: Config) -> tuple[OverloadProtection, ...]:
    """Each joint's actuator model's protection (its `actuator`, else its chain's model)."""
    return tuple(protection_of(config.actuator_of(joint)) for joint in config.joints)


@dataclass(frozen=True)
class GuardRule:
    """The guard's timer per joint (module docstring): it runs up while |I| >= fraction x the
    current limit and fires at time_s; `margin_s` (derived rule) is how long before the
    protection's trip that is, None for the explicit rule."""

    fraction: np.ndarray
    time_s: np.ndarray
    protections: tuple[OverloadProtection, ...]
    margin_s: float | None

    @classmethod
    def of(cls, safety: SafetySection, protections: Sequence[OverloadProtection]) -> GuardRule:
        protections = tuple(protections)
        margin = safety.current_guard_margin_s
        if margin is None:
            n = len(protections)
            fraction = np.full(n, safety.current_guard_fraction)
            time_s = np.full(n, safety.current_guard_time_s)
            return cls(fraction, time_s, protections, None)
        for protection in protections:
            if not margin < protection.trip_time_s:
                raise ValueError(
                    f"[safety] current_guard_margin_s = {margin:g} s is not below the "
                    f"{protection.model}'s overload trip time ({protection.trip_time_s:g} s)"
                )
        fraction = np.array([p.fraction for p in protections])
        time_s = np.array([p.trip_time_s - margin for p in protections])
        return cls(fraction, time_s, protections, margin)

    def describe(self, joint: int) -> str:
        protection = self.protections[joint]
        if self.margin_s is None:
            return (
                f">= {self.fraction[joint]:.0%} of the limit for a net {self.time_s[joint]:g} s "
                f"(fixed: current_guard_fraction, current_guard_time_s)"
            )
        return (
            f"the {protection.model}'s overload timer (>= {protection.fraction:.0%} of the limit, "
            f"net; trips at {protection.trip_time_s:g} s) at {self.time_s[joint]:g} s: "
            f"current_guard_margin_s = {self.margin_s:g} s before the protection"
        )

    def record(self, names: Sequence[str]) -> dict[str, object]:
        """The rule for summary.json, per joint name."""
        return {
            "rule": "fixed" if self.margin_s is None else "protection",
            "margin_s": self.margin_s,
            "fraction": dict(zip(names, self.fraction.tolist(), strict=True)),
            "fires_at_s": dict(zip(names, self.time_s.tolist(), strict=True)),
            "protection": {
                p.model: {"fraction": p.fraction, "trip_time_s": p.trip_time_s, "source": p.source}
                for p in self.protections
            },
        }
