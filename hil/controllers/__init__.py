"""Controllers: the contract every controller keeps, the registry of the built-in ones and the
plug-ins, and the controller's model of the robot.

contract.py       what a controller gets and gives each tick (`Controller`, `ControlInput`,
                  `ControllerSetup`, `ControllerParams`)
registry.py       names -> controllers, and plug-ins from files, modules and entry points
paper.py          the paper's four controllers as registry entries
paper_factory.py  the paper's controllers' figures from the configuration
robot_model.py    the controller's model of the robot (Sm, gravity) from `[model]`
setup.py          a run's `ControllerSetup` from the configuration
preflight.py      a plug-in tried once on a copy before a run
"""

from hil.controllers.contract import (
    ControlInput,
    Controller,
    ControllerFailure,
    ControllerParams,
    ControllerSetup,
    NoParams,
)
from hil.controllers.registry import (
    BUILT_IN,
    ENTRY_POINT_GROUP,
    ControllerLoadError,
    available,
    build,
    controller_class,
    controller_params,
    resolve,
)

__all__ = [
    "BUILT_IN",
    "ENTRY_POINT_GROUP",
    "ControlInput",
    "Controller",
    "ControllerFailure",
    "ControllerLoadError",
    "ControllerParams",
    "ControllerSetup",
    "NoParams",
    "available",
    "build",
    "controller_class",
    "controller_params",
    "resolve",
]
