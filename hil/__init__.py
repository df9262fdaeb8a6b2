"""flexjoint-hil: the 200 Hz loop of Kim et al., ICRA 2018 (gravity compensator + DOB + LQR)
on flexible-joint, position-controlled actuators, on hardware and on a byte-exact emulation.

The public surface, one page (each name is documented where it is defined):

    open_robot, Robot, RobotLoop, Setup, RunStopped
                        the robot a configuration describes, a run of an experiment on it,
                        and your own 200 Hz loop through the supervisor (hil/api.py)
    RunResult           how a run ended, its metrics, its directory, its exit status
    load_run, Run       a run directory read back: arrays per signal and joint, a long table
                        (hil/output/run_data.py; `hil compare` overlays runs)
    JointSample         one reading of every joint, in SI units (drivers/joint_bus.py)
    Controller, ControllerParams, ControllerSetup, ControlInput
                        the controller contract: write your own (hil/controllers/contract.py)
    Experiment, World   the experiment contract (hil/experiments/base.py)
    ConfigError         what bad input raises, before anything opens
    __version__         the installed version

Everything is imported on first use, so that `import hil` stays cheap and importing one
sub-package does not import them all.
"""

from __future__ import annotations

import os
from importlib import import_module, metadata
from typing import TYPE_CHECKING

# One BLAS thread: the loop's matrices are small (12 joints: at most 48 x 48), where a thread
# pool costs more than it saves, and on a busy machine much more (measured on 2 shared cores:
# a 72 x 72 triangular solve 18.9 ms with OpenBLAS's threads, 0.46 ms with one). Set before
# numpy is first imported; a value the user set stays.
for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

try:
    __version__ = metadata.version("flexjoint-hil")
except metadata.PackageNotFoundError:  # a source tree that was not installed
    __version__ = "0+unknown"

# name -> the module that defines it
_EXPORTS = {
    "ConfigError": "hil.config",
    "Experiment": "hil.experiments.base",
    "JointSample": "drivers.joint_bus",
    "Robot": "hil.api",
    "RobotLoop": "hil.api",
    "Run": "hil.output.run_data",
    "RunResult": "hil.output.records",
    "RunStopped": "hil.api",
    "Setup": "hil.api",
    "World": "hil.experiments.base",
    "load_run": "hil.output.run_data",
    "open_robot": "hil.api",
    "ControlInput": "hil.controllers.contract",
    "Controller": "hil.controllers.contract",
    "ControllerParams": "hil.controllers.contract",
    "ControllerSetup": "hil.controllers.contract",
}

__all__ = [
    "ConfigError",
    "ControlInput",
    "Controller",
    "ControllerParams",
    "ControllerSetup",
    "Experiment",
    "JointSample",
    "Robot",
    "RobotLoop",
    "Run",
    "RunResult",
    "RunStopped",
    "Setup",
    "World",
    "__version__",
    "load_run",
    "open_robot",
]

if TYPE_CHECKING:
    from drivers.joint_bus import JointSample
    from hil.api import Robot, RobotLoop, RunStopped, Setup, open_robot
    from hil.config import ConfigError
    from hil.controllers.contract import (
        ControlInput,
        Controller,
        ControllerParams,
        ControllerSetup,
    )
    from hil.experiments.base import Experiment, World
    from hil.output.records import RunResult
    from hil.output.run_data import Run, load_run


def __getattr__(name: str) -> object:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'hil' has no attribute {name!r}")
    value = getattr(import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(__all__)
