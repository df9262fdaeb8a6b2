"""The paper's testbed comparison (Kim et al., ICRA 2018, Figs. 5 and 6), `hil run`:

- contact (Fig. 5) and impact (Fig. 6): pid, gc, gc+lqr, and gc+lqr+dob with Kdist 0.5 and 1,
  then the DOB once more (Kdist 1) with the other reading of the paper's (25), so the report
  shows what the choice of reading does (the lab's accumulated total vs the literal
  uc(tk - dt));
- contact held 30 s (`contact-long`): the DOB (Kdist 1) in the configured reading and in the
  bounded one ("accumulated-integral"; the lab's "accumulated" when the bounded one is the
  configured reading, so no run is made twice): does the compliance last, or does the force
  creep?
- impact held a minute (`impact-long`): the DOB with Kdist 1 and 0.5, long enough to see the
  equilibrium behind the paper's "steady-state error".
"""

from __future__ import annotations

from controller import CompositionReading
from hil.experiments import CONTACT, CONTACT_LONG, IMPACT, IMPACT_LONG
from hil.robots.profile import Comparison, Plan
from hil.vocabulary import ControllerChoice, ControllerKind

COMPARISON_CHOICES: tuple[ControllerChoice, ...] = (
    ControllerChoice(ControllerKind.PID),
    ControllerChoice(ControllerKind.GC),
    ControllerChoice(ControllerKind.GC_LQR),
    ControllerChoice(ControllerKind.GC_LQR_DOB, 0.5),
    ControllerChoice(ControllerKind.GC_LQR_DOB, 1.0),
)
OTHER_READING_KDIST = 1.0
BOUNDED_READING = CompositionReading.ACCUMULATED_INTEGRAL


def comparison_plan(default_reading: str, *, long_runs: bool = True) -> Plan:
    """The runs of the testbed comparison, in order (see the module docstring)."""
    accumulated = CompositionReading.ACCUMULATED
    other = CompositionReading.LITERAL if default_reading == accumulated else accumulated
    dob = ControllerKind.GC_LQR_DOB
    choices = [*COMPARISON_CHOICES, ControllerChoice(dob, OTHER_READING_KDIST, other)]
    plan = [(experiment, choice) for experiment in (CONTACT, IMPACT) for choice in choices]
    if long_runs:
        long_other = accumulated if default_reading == BOUNDED_READING else BOUNDED_READING
        plan += [
            (CONTACT_LONG, ControllerChoice(dob, 1.0)),
            (CONTACT_LONG, ControllerChoice(dob, 1.0, long_other)),
            (IMPACT_LONG, ControllerChoice(dob, 1.0)),
            (IMPACT_LONG, ControllerChoice(dob, 0.5)),
        ]
    return plan


TESTBED_COMPARISON = Comparison(
    name=None,
    directory="comparison",
    title="Testbed comparison: Kim et al., ICRA 2018, Figs. 5 and 6",
    claims_source="Kim et al., ICRA 2018, Sec. IV-B",
    plan=lambda config, long_runs: comparison_plan(
        config.controller.composition, long_runs=long_runs
    ),
)
