"""`[controller] dob_expects_gravity_lag` reaches the controller (hil/controllers/paper_factory.py):
on for the built-in DYROS-JET (its servo model is the cascade), off for the testbed's built-in
configuration (the paper's DOB), and on the humanoid the DOB it builds compares the motor with
the goal minus (1/(Kpp kv)) / C ug (controller/controllers.py; by hand in
tests/controller/test_dob_gravity_lag.py)."""

from __future__ import annotations

import numpy as np

from controller.humanoid import WALKING_READY_LEG_ANGLES_RAD, SupportState
from hil.config import load_config
from hil.controllers.paper_factory import build_controller
from hil.controllers.robot_model import robot_model
from hil.vocabulary import ControllerChoice


def test_the_humanoid_expects_the_servos_lag_and_the_testbed_does_not() -> None:
    jet = load_config(robot="dyros-jet")
    testbed = load_config()
    assert jet.controller.dob_expects_gravity_lag is True
    assert testbed.controller.dob_expects_gravity_lag is False
    choice = ControllerChoice("gc+lqr+dob", 0.2)
    robot = robot_model(jet)
    start = np.asarray(WALKING_READY_LEG_ANGLES_RAD)
    contact = robot.lqr_contacts([SupportState.DOUBLE])[0]
    controller = build_controller(jet, choice, 0.005, robot, start, contact)
    assert controller.params.dob_expects_gravity_lag is True
    kpp = np.array([jet.model.joint_figure(n, "position_gain_per_s") for n in jet.joint_names])
    servo = 1.0 / (kpp * jet.model.velocity_gain_nms_per_rad)
    expected = servo / controller.params.compensator_compliance_rad_per_nm
    assert np.allclose(controller._expected_lag_per_ug, expected)  # the knees' Kpp is 18
    assert build_controller(testbed, choice, 0.005).params.dob_expects_gravity_lag is False
