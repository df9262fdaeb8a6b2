"""What a robot is to hil (`RobotProfile`): one per robot, in its folder (hil/robots/<name>/),
registered in hil/robots/registry.py.

    robot         its name (`hil.vocabulary.Robot`: `[model] robot`, `--robot`)
    summary       its description in the CLI (`hil config --help`, `hil run --help`)
    emulated      what a run's banner calls its emulation ("emulated testbed")
    model         the controller's model of it from a configuration (`RobotModel`: Sm of (19)
                  and the gravity compensator (5)-(8))
    emulation     its emulated hardware from a configuration (`RobotEmulation`: the spec's
                  robot-specific parts, the truth behind `hil model`)
    experiments   the built-in experiments that run on it (`hil run NAME` picks it for them)
    bench_experiment  what `hil bench loop` runs on it (its first posture is where a
                  rescheduled robot's gain design is timed)
    comparisons   what `hil run` runs on it without an experiment (`Comparison`: the default,
                  name None, and named ones such as `hil run walking`)
    check         what its configuration must satisfy beyond the schema, checked before
                  anything opens (a URDF that builds its model, ...); ConfigError naming the key

Its built-in configuration is `hil/data/<name with _ for ->.toml` (`hil config --robot NAME`
prints it; hil.config.builtin_config_name).
"""

from __future__ import annotations

import abc
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from hil.config import Config
from hil.experiments import Experiment
from hil.robots.model import RobotModel
from hil.vocabulary import ControllerChoice, Robot

if TYPE_CHECKING:
    from sim_backend.plant import TestbedPlantParams
    from sim_backend.servo import H54ServoParams
    from sim_backend.spec import HardwareKind

Plan = list[tuple[Experiment, ControllerChoice]]


@dataclass(frozen=True)
class Comparison:
    """A comparison `hil run` runs on a robot: its runs in order and its report.

    name: `hil run NAME` (None: the robot's own, `hil run [--robot NAME]`).
    directory: the comparison's directory under --out, after its timestamp.
    plan: its runs from the configuration (and whether the long runs are wanted).
    rendered: the report draws the emulated robot at the paper's Fig. 8 instants.
    """

    name: str | None
    directory: str
    title: str
    claims_source: str
    plan: Callable[[Config, bool], Plan]
    rendered: bool = False


@dataclass(frozen=True)
class JointTruth:
    """Each emulated joint's figures behind `hil model`: its gear, its servo's SI figures and its
    Position P Gain register at power-on, in the configuration's joint order."""

    gear_stiffness_nm_per_rad: tuple[float, ...]
    servos: tuple[H54ServoParams, ...]
    power_on_position_gain_registers: tuple[int, ...]


class RobotEmulation(abc.ABC):
    """How a robot's emulated hardware is built from a configuration (hil/wiring/emulation.py
    asks; sim_backend builds the hardware of `kind`)."""

    kind: HardwareKind

    @abc.abstractmethod
    def plant(self, config: Config, overrides: Mapping[str, Any]) -> TestbedPlantParams:
        """The spec's `plant` with `[emulator] plant`'s overrides, which are checked against
        this robot's truth here (TypeError or ValueError naming the key)."""

    def start_overrides(self, start_rad: np.ndarray) -> dict[str, Any]:
        """Truth overrides that place the emulated robot where an experiment starts (its first
        reference per joint); none by default (the robot's own power-on posture)."""
        return {}

    @abc.abstractmethod
    def joint_truth(self, config: Config, servo: H54ServoParams) -> JointTruth:
        """The emulated joints' gears and servos (`servo`: [emulator] servo over the H54's)."""

    def spec_parts(
        self, config: Config, start_rad: np.ndarray | None, experiment: Experiment | None
    ) -> dict[str, Any]:
        """The spec's fields only this robot has (the humanoid's `humanoid`), from where the
        experiment starts (None: no experiment) and its world."""
        return {}


def no_check(config: Config) -> None:
    """A robot whose configuration the schema and the drivers check in full."""


@dataclass(frozen=True)
class RobotProfile:
    """One robot (see the module docstring)."""

    robot: Robot
    summary: str
    emulated: str
    model: Callable[[Config], RobotModel]
    emulation: RobotEmulation
    experiments: tuple[Experiment, ...]
    bench_experiment: Experiment
    comparisons: tuple[Comparison, ...]
    check: Callable[[Config], None] = no_check

    def comparison(self, name: str | None = None) -> Comparison:
        """Its default comparison (None) or the named one; KeyError if it has none such."""
        for comparison in self.comparisons:
            if comparison.name == name:
                return comparison
        raise KeyError(name)
