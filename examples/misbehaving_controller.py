"""A controller with a bug, to see what the safety net does for you.

It follows the reference for one second, then misbehaves as `[controller.params] fault` says:

    "nan"      returns a goal that is not a number
    "raise"    raises an exception
    "runaway"  drives the goal away at 1 rad/s (the supervisor limits the goal's rate, then the
               link deflects against the block until the deflection watch holds it)

    hil run contact --controller examples/misbehaving_controller.py:Misbehaving

The supervisor stops it: with "nan" and "raise" torque goes off at once (`controller_fault`,
the traceback in events.jsonl), and the run ends as a safety stop (exit status 1).
"""

from typing import Literal

import numpy as np

from hil import ControlInput, Controller, ControllerParams

GOOD_FOR_S = 1.0


class Misbehaving(Controller):
    """The reference as the goal, until GOOD_FOR_S into the experiment."""

    class Params(ControllerParams):
        fault: Literal["nan", "raise", "runaway"] = "nan"

    needs_link_angle = False

    def start(self, state: ControlInput) -> None:
        self.runaway_rad = 0.0

    def step(self, state: ControlInput) -> np.ndarray:
        if state.time_s < GOOD_FOR_S:
            return state.reference_rad.copy()
        if self.params.fault == "raise":
            raise ZeroDivisionError("a bug in the controller")
        if self.params.fault == "nan":
            return np.full(self.setup.n_joints, np.nan)
        self.runaway_rad += 1.0 * self.setup.period_s
        return state.reference_rad + self.runaway_rad
