"""The paper's two testbed experiments, as data (Kim et al., ICRA 2018, Sec. IV-B).

An experiment is a reference trajectory for the link, what the world does to the testbed
(where the obstacle is, when the load is pushed), a duration, and the metrics it reports. On the
real testbed the world part is physical (you place the block, you push the load); the emulator
builds it from the same figures (`hil emulate --experiment NAME`).

Figures the paper does not publish are parameters here, each with its reason:
- contact (Fig. 5): the link starts horizontal, holds 1 s, then its reference moves 0.3 rad down
  over 2 s (a cosine ramp) and holds there; the block is 0.2 rad below horizontal, so contact
  happens near t = 2.2 s (the paper: "at 2.3 s"). The reference ends 0.1 rad past the block:
  the position servo then demands 0.1 rad x 785 N m/rad, more than its 48 N m current limit,
  which is what drives it into its overload protection.
- impact (Fig. 6): the link holds horizontal; at t = 1 s the load gets an 80 N push (the paper's
  figure) downwards for 20 ms (a hand or hammer strike; the duration is not published).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Ramp:
    """Cosine ramp of the reference from `start_rad` to `end_rad` between two times."""

    start_s: float
    duration_s: float
    start_rad: float
    end_rad: float

    def value(self, time_s: float) -> float:
        if time_s <= self.start_s:
            return self.start_rad
        if time_s >= self.start_s + self.duration_s:
            return self.end_rad
        phase = (time_s - self.start_s) / self.duration_s
        return self.start_rad + (self.end_rad - self.start_rad) * 0.5 * (
            1 - math.cos(math.pi * phase)
        )


@dataclass(frozen=True)
class Push:
    """A push on the load, perpendicular to the link; negative force pushes the load down."""

    start_s: float
    duration_s: float
    force_n: float


@dataclass(frozen=True)
class Obstacle:
    """The block with its force sensor: the link angle at which the load touches it."""

    contact_angle_rad: float


@dataclass(frozen=True)
class Experiment:
    name: str
    title: str
    duration_s: float
    initial_angle_rad: float
    ramps: tuple[Ramp, ...] = ()
    obstacle: Obstacle | None = None
    pushes: tuple[Push, ...] = ()
    notes: str = ""
    metrics: tuple[str, ...] = field(default_factory=tuple)

    def reference(self, time_s: float) -> float:
        """The desired link angle [rad] at time_s (ramps applied in order)."""
        value = self.initial_angle_rad
        for ramp in self.ramps:
            if time_s >= ramp.start_s:
                value = ramp.value(time_s)
        return value

    def reference_array(self, times_s: np.ndarray) -> np.ndarray:
        return np.array([self.reference(float(t)) for t in times_s])

    @property
    def min_reference_rad(self) -> float:
        return min([self.initial_angle_rad, *(r.end_rad for r in self.ramps)])

    @property
    def max_reference_rad(self) -> float:
        return max([self.initial_angle_rad, *(r.end_rad for r in self.ramps)])


CONTACT = Experiment(
    name="contact",
    title="Object contact (Fig. 5): the reference drives the link into a block",
    duration_s=8.0,
    initial_angle_rad=0.0,
    ramps=(Ramp(start_s=1.0, duration_s=2.0, start_rad=0.0, end_rad=-0.3),),
    obstacle=Obstacle(contact_angle_rad=-0.2),
    metrics=(
        "peak_contact_force_n",
        "mean_contact_force_n",
        "overload_tripped",
        "trip_time_after_contact_s",
    ),
)

IMPACT = Experiment(
    name="impact",
    title="Impact (Fig. 6): an 80 N push on the load while holding",
    duration_s=5.0,
    initial_angle_rad=0.0,
    pushes=(Push(start_s=1.0, duration_s=0.02, force_n=-80.0),),
    metrics=("first_peak_rad", "settling_time_s", "steady_state_error_rad"),
)

EXPERIMENTS: dict[str, Experiment] = {e.name: e for e in (CONTACT, IMPACT)}


def get_experiment(name: str) -> Experiment:
    try:
        return EXPERIMENTS[name]
    except KeyError:
        raise ValueError(
            f"unknown experiment {name!r}; choose one of {sorted(EXPERIMENTS)}"
        ) from None
