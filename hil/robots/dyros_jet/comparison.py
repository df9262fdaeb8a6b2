"""DYROS-JET's comparisons (Kim et al., ICRA 2018, Sec. IV-C):

- `hil run --robot dyros-jet`: stand and push, each with pid, gc, gc+lqr and gc+lqr+dob (the
  configuration's Kdist: the lab's stance 0.2), and gc once more with the paper's literal (8);
- `hil run walking`: walk-slow, walk-dynamic and step-on-object, each with the same five
  (Kdist by phase: the configuration's on the stance leg, 1.0 on the landing leg), Figs. 7, 8.
"""

from __future__ import annotations

from controller.gravity import GcCompliance
from hil.experiments import PUSH, STAND, STEP_ON_OBJECT, WALK_DYNAMIC, WALK_SLOW
from hil.robots.profile import Comparison, Plan
from hil.vocabulary import ControllerChoice, ControllerKind


def humanoid_choices(kdist: float) -> tuple[ControllerChoice, ...]:
    """The four controllers, and GC once more with the other reading of (8): the paper's
    literal K^-1 ("gear") beside the configuration's (the whole joint's, by default)."""
    return (
        ControllerChoice(ControllerKind.PID),
        ControllerChoice(ControllerKind.GC),
        ControllerChoice(ControllerKind.GC, gc_compliance=GcCompliance.GEAR),
        ControllerChoice(ControllerKind.GC_LQR),
        ControllerChoice(ControllerKind.GC_LQR_DOB, kdist),
    )


def humanoid_plan(kdist: float) -> Plan:
    """DYROS-JET standing and pushed, with each of `humanoid_choices`."""
    choices = humanoid_choices(kdist)
    return [(experiment, choice) for experiment in (STAND, PUSH) for choice in choices]


def walking_plan(kdist: float) -> Plan:
    """DYROS-JET walking slowly, dynamically and onto an object, with each of
    `humanoid_choices`."""
    choices = humanoid_choices(kdist)
    return [
        (experiment, choice)
        for experiment in (WALK_SLOW, WALK_DYNAMIC, STEP_ON_OBJECT)
        for choice in choices
    ]


STANDING_COMPARISON = Comparison(
    name=None,
    directory="humanoid-comparison",
    title="DYROS-JET standing and pushed: Kim et al., ICRA 2018, Sec. IV-C",
    claims_source="Kim et al., ICRA 2018, Sec. III-A, IV-C",
    plan=lambda config, long_runs: humanoid_plan(config.controller.kdist),
)
WALKING_COMPARISON = Comparison(
    name="walking",
    directory="walking-comparison",
    title="DYROS-JET walking: Kim et al., ICRA 2018, Sec. IV-C, Figs. 7 and 8",
    claims_source="Kim et al., ICRA 2018, Sec. III-A, IV-C",
    plan=lambda config, long_runs: walking_plan(config.controller.kdist),
    rendered=True,
)
