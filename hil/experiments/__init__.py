"""The experiments, one module each (see `base.py` for what an experiment holds).

    contact       Kim et al., ICRA 2018, Fig. 5: the link driven into a block
    impact        Kim et al., ICRA 2018, Fig. 6: an 80 N push while holding
    contact-long  the contact held 30 s: does the compliance last?
    impact-long   the impact held a minute: the error after the push at its equilibrium
    stand         DYROS-JET's legs hold the walking-ready posture (double support)
    push          the same, pushed at the pelvis
    identify      a chirp on the goal with the link free, open loop: the log `hil identify` fits
    walk-slow     DYROS-JET walks, 0.8 s single / 3.2 s double support (Fig. 7(a))
    walk-dynamic  the same at 0.8 s / 0.3 s (Fig. 7(b))
    step-on-object  the dynamic walk over a box the plan does not know (Fig. 8)

`EXPERIMENTS` maps names to experiments; `get_experiment(name)` gives a clear error for a
name that does not exist.
"""

from hil.experiments.base import Experiment, Obstacle, Push, Ramp, TestbedExperiment, World
from hil.experiments.contact import CONTACT, CONTACT_LONG
from hil.experiments.humanoid import PUSH, STAND
from hil.experiments.identify import IDENTIFY, IdentifyExperiment
from hil.experiments.impact import IMPACT, IMPACT_LONG
from hil.experiments.walking import STEP_ON_OBJECT, WALK_DYNAMIC, WALK_SLOW

EXPERIMENTS: dict[str, Experiment] = {
    e.name: e
    for e in (
        CONTACT,
        IMPACT,
        CONTACT_LONG,
        IMPACT_LONG,
        IDENTIFY,
        STAND,
        PUSH,
        WALK_SLOW,
        WALK_DYNAMIC,
        STEP_ON_OBJECT,
    )
}
# Which robot each experiment is for (`hil run NAME` picks the robot's built-in configuration).
ROBOT_OF_EXPERIMENT: dict[str, str] = {
    name: "dyros-jet" for name in ("stand", "push", "walk-slow", "walk-dynamic", "step-on-object")
}


def robot_of_experiment(name: str | None) -> str:
    """The built-in robot an experiment runs on ("testbed" for the paper's 1-DoF testbed and
    for the comparison, name None)."""
    return ROBOT_OF_EXPERIMENT.get(name, "testbed") if name else "testbed"


def get_experiment(name: str) -> Experiment:
    try:
        return EXPERIMENTS[name]
    except KeyError:
        raise ValueError(
            f"unknown experiment {name!r}; choose one of {sorted(EXPERIMENTS)}"
        ) from None


__all__ = [
    "CONTACT",
    "CONTACT_LONG",
    "EXPERIMENTS",
    "IDENTIFY",
    "IMPACT",
    "IMPACT_LONG",
    "PUSH",
    "ROBOT_OF_EXPERIMENT",
    "STAND",
    "STEP_ON_OBJECT",
    "WALK_DYNAMIC",
    "WALK_SLOW",
    "Experiment",
    "IdentifyExperiment",
    "Obstacle",
    "Push",
    "Ramp",
    "TestbedExperiment",
    "World",
    "get_experiment",
    "robot_of_experiment",
]
