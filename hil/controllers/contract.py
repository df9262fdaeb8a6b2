"""The controller contract: what a controller of n flexible joints gets and gives each tick.

A controller is a class. The loop builds one per run from the robot it runs on
(`ControllerSetup`) and the controller's own parameters (`Controller.Params`, a pydantic model
filled from the configuration's `[controller.params]` table), then, every tick of the
experiment on which it may act, hands it a `ControlInput` and sends the goal it returns:

    start(state)   once, on the first tick of the experiment, before the first `step`: a
                   bumpless start from `state.goal_in_force_rad` (the goal the actuators'
                   servos are being driven with; under a load the servo rests short of it)
    step(state)    every tick after that (and on the first, after `start`): the goal motor
                   angle per joint [rad], an array of shape (n,), finite
    applied(goal)  after every step: the goal really sent (the supervisor may have limited it)
    terms()        after every step: the named per-joint parts of the goal to log, one array
                   of shape (n,) per name in `term_names` (log.csv columns `name[joint]`)

Units are SI (rad, rad/s, A, N m, s). Angles are link-side joint angles for the link and the
motor's angle through the gear on the same scale (the motor angle equals the link angle when
the gear carries no torque). The goal is the MOTOR angle the actuator's own position servo is
asked to hold. The loop does not step the controller on ticks on which it cannot (the
supervisor holds a safe state, a reading is missing); `state.ticks_since_step` says how many
ticks passed since the last step (1 normally), so a controller that differences its samples
can tell a gap from motion.

What a controller declares (class attributes):

    Params            its parameters' schema (a `ControllerParams` subclass: a pydantic model,
                      extra keys refused), default: none
    term_names        the names of the terms it logs (each a log.csv column per joint: a unit
                      suffix such as `_rad` is expected), default: none
    needs_link_angle  True (default) if it reads `link_angle_rad`: refused before the first
                      byte on a robot without link encoders
    uses_kdist        True if it has the paper's DOB gain Kdist (`--kdist`, `[safety]
                      max_kdist`, an experiment's Kdist schedule, `set_kdist`)

A controller that raises, returns a goal of the wrong shape or not finite, is stopped by the
supervisor: torque off, the traceback in the run's events.jsonl. A plug-in is also tried once
before the run on a copy, at the experiment's start posture (`hil.controllers.preflight`).

Example, a PD on the link angle with gravity feed-forward (examples/pd_gravity.py has it whole)::

    import numpy as np
    from pydantic import Field
    from hil import ControlInput, Controller, ControllerParams, ControllerSetup

    class PdGravity(Controller):
        class Params(ControllerParams):
            kp: float = Field(0.5, gt=0, le=5)  # rad of goal per rad of link error

        term_names = ("feedforward_rad",)

        def __init__(self, setup: ControllerSetup, params: Params) -> None:
            super().__init__(setup, params)
            self.compliance = 1.0 / setup.stiffness_nm_per_rad

        def start(self, state: ControlInput) -> None:
            self.feedforward = np.zeros(self.setup.n_joints)

        def step(self, state: ControlInput) -> np.ndarray:
            tau = self.setup.gravity_torque(state.reference_rad)
            self.feedforward = self.compliance * tau
            error = state.reference_rad - state.link_angle_rad
            return state.reference_rad + self.params.kp * error + self.feedforward

        def terms(self) -> dict[str, np.ndarray]:
            return {"feedforward_rad": self.feedforward}
"""

from __future__ import annotations

import abc
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import numpy as np
from pydantic import BaseModel, ConfigDict

if TYPE_CHECKING:
    from controller import PlannedMotion
    from hil.config import Config
    from hil.controllers.robot_model import RobotModel


class ControllerParams(BaseModel):
    """The base of a controller's parameter schema: `[controller.params]` of the configuration
    file, validated by pydantic (unknown keys refused, numbers not coerced from strings)."""

    model_config = ConfigDict(extra="forbid", strict=True, frozen=True)


class NoParams(ControllerParams):
    """A controller without parameters: `[controller.params]` must be empty."""


@dataclass(frozen=True)
class ControllerSetup:
    """The robot a controller is built for: fixed for the run.

    joint_names        the joints, in the order of every array
    period_s           the loop's period [s]
    stiffness_nm_per_rad, damping_nms_per_rad, servo_gain_per_s
                       the nominal model per joint, from `[model]`: the gear's K and D, the
                       servo's first-order gain Kp of (4) [N m/rad, N m s/rad, 1/s]
    robot              the controller's model of the robot (hil/controllers/robot_model.py):
                       its gravity and Sm; `gravity_torque` and `sm` below are the short way
    start_reference_rad  the experiment's reference at its start [rad]
    start_contact      the LQR's contact there (the humanoid's feet; None on the testbed)
    config             the whole configuration (what the built-in controllers read)
    """

    joint_names: tuple[str, ...]
    period_s: float
    stiffness_nm_per_rad: np.ndarray
    damping_nms_per_rad: np.ndarray
    servo_gain_per_s: np.ndarray
    robot: RobotModel
    start_reference_rad: np.ndarray
    start_contact: object
    config: Config

    @property
    def n_joints(self) -> int:
        return len(self.joint_names)

    def gravity_torque(self, link_angle_rad: np.ndarray) -> np.ndarray:
        """tau_g: the torque per joint [N m] that holds the links still at these angles (on the
        humanoid for the support state of the tick: the loop keeps it current)."""
        return np.asarray(self.robot.gravity.gravity_torque(np.asarray(link_angle_rad, float)))

    def sm(self, link_angle_rad: np.ndarray) -> np.ndarray:
        """Sm of (19) at these link angles (n x n) [1/(kg m^2)], for the start's contact."""
        return self.robot.sm(np.asarray(link_angle_rad, float), self.start_contact)


@dataclass(frozen=True)
class ControlInput:
    """One tick, as the controller sees it (arrays of shape (n,), SI units; do not change them).

    tick               the loop's tick index (200 Hz grid)
    time_s             experiment time [s] (0 where the experiment's reference starts)
    motor_angle_rad    the actuators' angles, through the gear [rad]
    link_angle_rad     the link encoders' angles [rad] (the last valid reading of each)
    motor_velocity_rad_s, motor_current_a   the actuators' own readings
    reference_rad      the desired link angle [rad]
    goal_in_force_rad  the goal sent last tick [rad]
    ticks_since_step   ticks since this controller's last step (1 normally; 0 before its first)
    support            on a humanoid, which feet carry it (`controller.humanoid.SupportState`),
                       else None
    planned_motion     what a walking plan says beyond the reference, or None
    """

    tick: int
    time_s: float
    motor_angle_rad: np.ndarray
    link_angle_rad: np.ndarray
    motor_velocity_rad_s: np.ndarray
    motor_current_a: np.ndarray
    reference_rad: np.ndarray
    goal_in_force_rad: np.ndarray
    ticks_since_step: int
    support: object | None = None
    planned_motion: PlannedMotion | None = None


class Controller(abc.ABC):
    """One controller for n joints; see the module docstring for the contract."""

    Params: ClassVar[type[ControllerParams]] = NoParams
    term_names: ClassVar[tuple[str, ...]] = ()
    needs_link_angle: ClassVar[bool] = True
    uses_kdist: ClassVar[bool] = False

    def __init__(self, setup: ControllerSetup, params: ControllerParams) -> None:
        self.setup = setup
        self.params = params

    @abc.abstractmethod
    def start(self, state: ControlInput) -> None:
        """Before the first step: start bumplessly from `state.goal_in_force_rad`."""

    @abc.abstractmethod
    def step(self, state: ControlInput) -> np.ndarray:
        """The goal motor angle per joint [rad] for this tick."""

    def applied(self, goal_rad: np.ndarray) -> None:  # noqa: B027 - optional
        """The goal really sent after the last step (clipped by the supervisor or not)."""

    def terms(self) -> Mapping[str, np.ndarray]:
        """The last step's logged terms, one array of shape (n,) per name in `term_names`."""
        return {}

    def set_kdist(self, kdist: np.ndarray) -> None:
        """Only for `uses_kdist` controllers: the DOB gain per joint from now on."""
        raise TypeError(f"{type(self).__name__} has no Kdist (uses_kdist is False)")


class ControllerFailure(RuntimeError):
    """A controller broke its contract during a run (raised, wrong shape, not finite): the
    supervisor stops the run with torque off."""
