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
    refused = link_angle_refusal(choice, config)
    if refused is not None:
        raise ControllerLoadError(refused)
    controller_params(choice.ref, choice, config.controller.params)
    if not choice.ref.built_in:
        problem = preflight(config, experiment, choice)
        if problem is not None:
            raise ControllerLoadError(f"{choice.ref.spec.removeprefix('file:')}: {problem}")
    return choice


def link_angle_refusal(choice: ControllerChoice, config: Config) -> str | None:
    """Why a controller cannot run on this robot: it reads the link angle (the LQR's state, the
    DOB inside one) and some joints have no link encoder (`encoder_node_id = 0`), where the
    bus reports the motor angle in its place (the gear's deflection unseen). None: it can."""
    bare = list(config.joints_without_link_encoder)
    if not (bare and choice.ref.needs_link_angle):
        return None
    return (
        f"{choice.name} needs the link angle, and joints {bare} have no link encoder "
        "([[joint]] encoder_node_id = 0); on such a robot pid and gc run (the motor encoders "
        "alone)"
    )
