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
    suspended-chirp DYROS-JET hung by its pelvis, each leg joint chirped in turn, open loop:
                  the log `hil twin` fits the legs from

Each robot's profile (hil/robots/<name>/) lists the experiments that run on it; the registry,
`hil.robots.EXPERIMENTS` and `hil.robots.get_experiment(name)`, is where `hil run NAME` looks
a name up, and loads a plug-in experiment (`plugin_experiment`: "path/to/file.py:Name" or
"package.module:Name", an `Experiment` instance or a subclass made with no arguments; its
`robot` attribute names the robot it is for, hil.vocabulary.Robot, the testbed by default).
"""

import inspect

from hil.experiments.base import Experiment, Obstacle, Push, Ramp, TestbedExperiment, World
from hil.experiments.contact import CONTACT, CONTACT_LONG
from hil.experiments.humanoid import PUSH, STAND
from hil.experiments.identify import IDENTIFY, IdentifyExperiment
from hil.experiments.impact import IMPACT, IMPACT_LONG
from hil.experiments.suspended import SUSPENDED_CHIRP, SuspendedChirpExperiment
from hil.experiments.walking import STEP_ON_OBJECT, WALK_DYNAMIC, WALK_SLOW
from hil.plugins import PluginError, class_from_target, target_of


def plugin_experiment(name: str) -> Experiment:
    """A plug-in experiment by where it is ("path/to/file.py:Name" or "package.module:Name"):
    an `Experiment` instance, or a subclass made with no arguments. ValueError saying why not."""
    try:
        found = class_from_target(target_of(name), name)
    except PluginError as exc:
        raise ValueError(str(exc)) from None
    if isinstance(found, type) and issubclass(found, Experiment):
        if inspect.isabstract(found):
            missing = ", ".join(f"{m}()" for m in sorted(found.__abstractmethods__))
            raise ValueError(f"{name}: {found.__name__} does not define {missing}")
        try:
            found = found()
        except Exception as exc:  # noqa: BLE001 - the user's constructor, said
            raise ValueError(
                f"{name}: {found.__name__}() raised {type(exc).__name__}: {exc}"
            ) from None
    if not isinstance(found, Experiment):
        raise ValueError(
            f"{name}: not an experiment: subclass hil.experiments.Experiment (see "
            "hil/experiments/base.py for its hooks)"
        )
    return found


__all__ = [
    "CONTACT",
    "CONTACT_LONG",
    "IDENTIFY",
    "IMPACT",
    "IMPACT_LONG",
    "PUSH",
    "STAND",
    "STEP_ON_OBJECT",
    "SUSPENDED_CHIRP",
    "WALK_DYNAMIC",
    "WALK_SLOW",
    "Experiment",
    "IdentifyExperiment",
    "Obstacle",
    "Push",
    "Ramp",
    "SuspendedChirpExperiment",
    "TestbedExperiment",
    "World",
    "plugin_experiment",
]
