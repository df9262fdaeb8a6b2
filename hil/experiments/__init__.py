"""The experiments, one module each (see `base.py` for what an experiment holds).

    contact       Kim et al., ICRA 2018, Fig. 5: the link driven into a block
    impact        Kim et al., ICRA 2018, Fig. 6: an 80 N push while holding
    contact-long  the contact held 30 s: does the compliance last?
    impact-long   the impact held a minute: the error after the push at its equilibrium
    stand         DYROS-JET's legs hold the walking-ready posture (double support)
    push          the same, pushed at the pelvis
    identify      a chirp on the goal with the link free, open loop: the log `hil identify` fits

`EXPERIMENTS` maps names to experiments; `get_experiment(name)` gives a clear error for a
name that does not exist.
"""

from hil.experiments.base import Experiment, Obstacle, Push, Ramp, TestbedExperiment, World
from hil.experiments.contact import CONTACT, CONTACT_LONG
from hil.experiments.humanoid import PUSH, STAND
from hil.experiments.identify import IDENTIFY, IdentifyExperiment
from hil.experiments.impact import IMPACT, IMPACT_LONG

EXPERIMENTS: dict[str, Experiment] = {
    e.name: e for e in (CONTACT, IMPACT, CONTACT_LONG, IMPACT_LONG, IDENTIFY, STAND, PUSH)
}
# Which robot each experiment is for (`hil run NAME` picks the robot's built-in configuration).
ROBOT_OF_EXPERIMENT: dict[str, str] = {"stand": "dyros-jet", "push": "dyros-jet"}


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
