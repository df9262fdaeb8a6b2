"""The paper's four controllers (Kim et al., ICRA 2018, Sec. IV) as entries of the registry.

Each wraps one of `controller.controllers` (the math, pure) behind the contract
(hil/controllers/contract.py): "pid" (the actuator's own position control), "gc" (the gravity
compensator (8) alone), "gc+lqr" (GC + the LQR (21)-(24)) and "gc+lqr+dob" (GC + LQR + the DOB
(9)-(11), composed by (25)). They log the parts of the goal u = uc + d_hat + ug (log.csv's
`uc_rad`, `d_hat_rad`, `ug_rad`). Their figures come from the configuration's `[model]` and
`[controller]`; what a run chooses beyond those (the DOB's Kdist, a reading of (25), the
compliance of (8)) is their `Params`, filled from the run's `ControllerChoice`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

import numpy as np
from pydantic import Field

from controller import COMPOSITION_READINGS, GcCompliance, JointController
from hil.controllers.contract import ControlInput, Controller, ControllerParams, ControllerSetup
from hil.controllers.paper_factory import build_controller
from hil.vocabulary import ControllerChoice, ControllerKind

PAPER_TERMS = ("uc_rad", "d_hat_rad", "ug_rad")


class PaperParams(ControllerParams):
    """What a run of one of the paper's controllers chooses (`ControllerChoice`)."""

    kdist: float = Field(0.0, ge=0)
    reading: str | None = None  # one of COMPOSITION_READINGS; None: [controller] composition
    gc_compliance: GcCompliance | None = None  # None: [controller] gc_compliance


class PaperController(Controller):
    """One of the paper's controllers (`kind`) through the contract."""

    kind: ClassVar[ControllerKind]
    Params = PaperParams
    term_names = PAPER_TERMS

    def __init__(self, setup: ControllerSetup, params: ControllerParams) -> None:
        assert isinstance(params, PaperParams)
        if params.reading is not None and params.reading not in COMPOSITION_READINGS:
            raise ValueError(f"reading must be one of {COMPOSITION_READINGS}")
        super().__init__(setup, params)
        self.choice = ControllerChoice(
            self.kind, params.kdist, params.reading, params.gc_compliance
        )
        # the paper's math, its LQR designed on Sm at the experiment's start posture
        self.joint_controller: JointController = build_controller(
            setup.config,
            self.choice,
            setup.period_s,
            setup.robot,
            setup.start_reference_rad,
            setup.start_contact,
        )
        self._zeros = np.zeros(setup.n_joints)

    @classmethod
    def params_of(cls, choice: ControllerChoice) -> PaperParams:
        return PaperParams(
            kdist=choice.kdist, reading=choice.reading, gc_compliance=choice.gc_compliance
        )

    def start(self, state: ControlInput) -> None:
        self.joint_controller.reset(
            state.motor_angle_rad,
            state.link_angle_rad,
            state.reference_rad,
            state.goal_in_force_rad,
        )

    def step(self, state: ControlInput) -> np.ndarray:
        controller = self.joint_controller
        if state.ticks_since_step > 1:  # ticks without a step: do not read them as motion
            controller.resync(state.motor_angle_rad, state.link_angle_rad)
        controller.set_planned_motion(state.planned_motion)
        return controller.step(state.motor_angle_rad, state.link_angle_rad, state.reference_rad)

    def applied(self, goal_rad: np.ndarray) -> None:
        self.joint_controller.notify_applied(goal_rad)

    def terms(self) -> Mapping[str, np.ndarray]:
        terms = self.joint_controller.terms
        return {"uc_rad": terms.uc, "d_hat_rad": terms.d_hat, "ug_rad": terms.ug}

    def set_kdist(self, kdist: np.ndarray) -> None:
        self.joint_controller.set_kdist(kdist)


class Pid(PaperController):
    """The actuator's own position control: the desired link angle is the goal (the paper's
    baseline "PID")."""

    kind = ControllerKind.PID
    needs_link_angle = False


class Gc(PaperController):
    """The gravity compensator (8) alone: u = theta_d + ug(theta_d)."""

    kind = ControllerKind.GC
    needs_link_angle = False


class GcLqr(PaperController):
    """GC + the discrete derivative-form LQR (21)-(24): u = uc + ug."""

    kind = ControllerKind.GC_LQR


class GcLqrDob(PaperController):
    """GC + LQR + the DOB (9)-(11), composed by (25) in the chosen reading."""

    kind = ControllerKind.GC_LQR_DOB
    uses_kdist = True
