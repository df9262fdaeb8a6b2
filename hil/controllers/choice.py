"""A run's controller chosen and checked before anything opens: the same checks for `hil run`
and for `hil.Robot.run`."""

from __future__ import annotations

from typing import TYPE_CHECKING

from hil.controllers.preflight import preflight
from hil.controllers.registry import ControllerLoadError, controller_params, resolve
from hil.vocabulary import ControllerChoice

if TYPE_CHECKING:
    from hil.config import Config
    from hil.experiments import Experiment


def choose(spec: str, config: Config, experiment: Experiment) -> ControllerChoice:
    """The controller `spec` names for this run of `experiment` on `config`'s robot (Kdist from
    `[controller] kdist`), its parameters checked by its schema and a plug-in tried once on a
    copy (hil/controllers/preflight.py); a ControllerLoadError says what is wrong."""
    choice = ControllerChoice(resolve(spec), config.controller.kdist)
    controller_params(choice.ref, choice, config.controller.params)
    if not choice.ref.built_in:
        problem = preflight(config, experiment, choice)
        if problem is not None:
            raise ControllerLoadError(f"{choice.ref.spec.removeprefix('file:')}: {problem}")
    return choice
