"""The robots, one folder each (hil/robots/<name>/: its profile, `RobotProfile`), and the
registry built from them (registry.py, one line a robot): what a configuration's robot is to
the rest of hil.

    profile(robot) / profile_of(config)   a robot's profile
    robot_model(config)                   the controller's model of the configured robot
    EXPERIMENTS / get_experiment(name)    every robot's built-in experiments by name (and a
                                          plug-in, "path/to/file.py:Name")
    robot_of_experiment(name)             the robot an experiment runs on
    NAMED_COMPARISONS                     `hil run NAME`'s comparisons, and their robot

Nothing outside a robot's folder and this registry compares a robot's name
(tests/hil/test_architecture.py checks it on the source).
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

from hil.config import Config
from hil.experiments import Experiment, plugin_experiment
from hil.robots.model import RobotModel
from hil.robots.profile import Comparison, RobotEmulation, RobotProfile
from hil.robots.registry import PROFILES
from hil.vocabulary import Robot

__all__ = [
    "EXPERIMENTS",
    "NAMED_COMPARISONS",
    "PROFILES",
    "Comparison",
    "RobotEmulation",
    "RobotModel",
    "RobotProfile",
    "get_experiment",
    "profile",
    "profile_of",
    "robot_model",
    "robot_of_experiment",
]


def profile(robot: Robot | str) -> RobotProfile:
    """The profile of `robot` (a Robot, or its name; ValueError naming the robots known)."""
    try:
        return PROFILES[Robot(robot)]
    except ValueError:
        raise ValueError(
            f"unknown robot {robot!r}; choose one of {[str(r) for r in PROFILES]}"
        ) from None


def profile_of(config: Config) -> RobotProfile:
    """The profile of the robot a configuration describes (`[model] robot`)."""
    return PROFILES[config.model.robot]


def robot_model(config: Config) -> RobotModel:
    """The controller's (nominal) model of the configured robot (its profile's `model`)."""
    return profile_of(config).model(config)


def _experiments() -> tuple[Mapping[str, Experiment], Mapping[str, Robot]]:
    table: dict[str, Experiment] = {}
    robots: dict[str, Robot] = {}
    for robot, each in PROFILES.items():
        for experiment in each.experiments:
            if experiment.name in table:
                raise ValueError(f"two robots name the experiment {experiment.name!r}")
            table[experiment.name] = experiment
            robots[experiment.name] = robot
    return MappingProxyType(table), MappingProxyType(robots)


EXPERIMENTS, _ROBOT_OF_EXPERIMENT = _experiments()
# `hil run NAME`: the named comparisons, and the robot each is for.
NAMED_COMPARISONS: Mapping[str, Robot] = MappingProxyType(
    {c.name: p.robot for p in PROFILES.values() for c in p.comparisons if c.name is not None}
)


def get_experiment(name: str) -> Experiment:
    """A built-in experiment by its name, or a plug-in by where it is ("path/to/file.py:Name",
    "package.module:Name"; hil.experiments.plugin_experiment). ValueError saying why not."""
    if name in EXPERIMENTS:
        return EXPERIMENTS[name]
    if ":" not in name:
        raise ValueError(
            f"unknown experiment {name!r}; choose one of {sorted(EXPERIMENTS)}, or your own as "
            "path/to/file.py:Name or package.module:Name"
        )
    return plugin_experiment(name)


def robot_of_experiment(name: str | None) -> Robot:
    """The robot an experiment runs on: its profile's, a plug-in's `robot` attribute (the
    testbed by default), and the testbed for the comparison (name None)."""
    if not name:
        return Robot.TESTBED
    if name in _ROBOT_OF_EXPERIMENT:
        return _ROBOT_OF_EXPERIMENT[name]
    declared = getattr(get_experiment(name), "robot", Robot.TESTBED)
    try:
        return Robot(declared)
    except ValueError:
        raise ValueError(
            f"{name}: its `robot` {declared!r} is none of {[str(r) for r in Robot]}"
        ) from None
