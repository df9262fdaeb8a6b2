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
name that does not exist, and loads a plug-in experiment ("path/to/file.py:Name" or
"package.module:Name": an `Experiment` instance, or a subclass made with no arguments; its
`robot` attribute names the built-in robot it is for, "testbed" by default).
"""

import inspect

from hil.experiments.base import Experiment, Obstacle, Push, Ramp, TestbedExperiment, World
from hil.experiments.contact import CONTACT, CONTACT_LONG
from hil.experiments.humanoid import PUSH, STAND
from hil.experiments.identify import IDENTIFY, IdentifyExperiment
from hil.experiments.impact import IMPACT, IMPACT_LONG
from hil.experiments.walking import STEP_ON_OBJECT, WALK_DYNAMIC, WALK_SLOW
from hil.plugins import PluginError, class_from_target, target_of

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
    if not name:
        return "testbed"
    if name in ROBOT_OF_EXPERIMENT or name in EXPERIMENTS:
        return ROBOT_OF_EXPERIMENT.get(name, "testbed")
    return str(getattr(get_experiment(name), "robot", "testbed"))


def get_experiment(name: str) -> Experiment:
    """A built-in experiment by its name, or a plug-in by where it is (module docstring)."""
    if name in EXPERIMENTS:
        return EXPERIMENTS[name]
    if ":" not in name:
        raise ValueError(
            f"unknown experiment {name!r}; choose one of {sorted(EXPERIMENTS)}, or your own as "
            "path/to/file.py:Name or package.module:Name"
        )
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
