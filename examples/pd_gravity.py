"""A PD on the link angle with gravity feed-forward, as a plug-in controller of `hil`.

Run it on the emulated testbed's contact and impact experiments, and on DYROS-JET standing:

    hil run contact --controller examples/pd_gravity.py:PdGravity
    hil run impact --controller examples/pd_gravity.py:PdGravity
    hil run stand --controller examples/pd_gravity.py:PdGravity

Its gains come from the configuration's `[controller.params]` (or `--param kp=0.3`), checked
by `Params` before anything opens. The goal is the motor angle the actuator's own servo holds.

What to expect: it holds and follows well (impact: a first peak of ~18 mrad, settled in ~0.5 s;
standing: no fall), but it is stiff: driven into the block (contact) it pushes as hard as the
actuator's own position control (~77 N) until the supervisor's current guard backs it off, a
safety stop. Compliance on contact is what the paper's DOB is for (`--controller gc+lqr+dob`).
"""

import numpy as np
from pydantic import Field

from hil import ControlInput, Controller, ControllerParams, ControllerSetup


class PdGravity(Controller):
    """u = theta_d + K^-1 tau_g(theta_d) + kp (theta_d - theta_j) - kd dtheta_m."""

    class Params(ControllerParams):
        kp: float = Field(0.5, ge=0, le=5)  # rad of goal per rad of link error
        kd_s: float = Field(0.005, ge=0, le=0.1)  # rad of goal per rad/s of motor velocity

    term_names = ("feedforward_rad", "feedback_rad")

    def __init__(self, setup: ControllerSetup, params: Params) -> None:
        super().__init__(setup, params)
        self.compliance = 1.0 / setup.stiffness_nm_per_rad  # the gear's, per joint [rad/N m]
        self.feedforward = self.feedback = np.zeros(setup.n_joints)

    def start(self, state: ControlInput) -> None:
        self.feedforward = self.feedback = np.zeros(self.setup.n_joints)

    def step(self, state: ControlInput) -> np.ndarray:
        self.feedforward = self.compliance * self.setup.gravity_torque(state.reference_rad)
        error = state.reference_rad - state.link_angle_rad
        self.feedback = self.params.kp * error - self.params.kd_s * state.motor_velocity_rad_s
        return state.reference_rad + self.feedforward + self.feedback

    def terms(self) -> dict[str, np.ndarray]:
        return {"feedforward_rad": self.feedforward, "feedback_rad": self.feedback}
