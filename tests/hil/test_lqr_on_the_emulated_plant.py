"""The LQR designs the configuration offers, closed around the linearised emulated robot
(sim_backend/humanoid/linear.py: MuJoCo's transition Jacobian with the H54 firmware, checked
against the nonlinear robot in tests/sim_backend/test_humanoid_linear.py), standing on both feet
and on one: what docs/humanoid.md's table of designs reports, as assertions.

- the closed-chain design on the paper's servo (4) is unstable at 2.4-2.9 Hz with the gearbox
  friction stuck (the emulated robot oscillates at 2.7 Hz: docs/studies/lqr_design) and at the
  Nyquist frequency when it slides;
- the paper's literal design (one support foot's Sm, diagonal, Euler) is unstable too;
- ours (the closed chain on the servo cascade, the configuration's default) keeps every
  oscillatory mode inside the unit circle on both sides of the friction, in double and single
  support; what is left near z = 1 is the servo's own velocity integrals (Ti = 15 s).
"""

from __future__ import annotations

import numpy as np
import pytest

from controller.humanoid import (
    WALKING_READY_LEG_ANGLES_RAD,
    LegModel,
    PostureTarget,
    SupportState,
    solve_posture,
)
from hil.config import load_config
from hil.loop import build_controller, robot_model
from hil.vocabulary import ControllerChoice
from sim_backend.humanoid.linear import Friction, linearise
from tests.support.humanoid_loop import URDF_PATH, closed_loop, loop_modes, settled_robot

PERIOD_S = 0.005
READY = np.array(WALKING_READY_LEG_ANGLES_RAD)
PAPER = {
    "model": {
        "sm_contact": "support-foot",
        "sm_coupling": "diagonal",
        "servo_model": "first-order",
    },
}
CLOSED_CHAIN = {"model": {"servo_model": "first-order"}}
FIRST_ORDER = {"controller": {"discretization": "euler", "r_input": 1.0}}


def _gain(changes: dict, angles: np.ndarray, support: SupportState):
    config = load_config(robot="dyros-jet")
    config = config.replaced(  # both sections at once: the cascade refuses Euler
        **{section: getattr(config, section).model_copy(update=v) for section, v in changes.items()}
    )
    robot = robot_model(config)
    contact = robot.lqr_contacts([support] * 3)[1]
    choice = ControllerChoice("gc+lqr", 1.0)
    return build_controller(config, choice, PERIOD_S, robot, angles, contact).lqr_gain


@pytest.fixture(scope="module")
def double_support():
    robot = settled_robot(READY, SupportState.DOUBLE, seconds=2.0)
    models = {f: linearise(robot, PERIOD_S, f) for f in Friction}
    return robot.plant.link_angle_rad, models


def test_the_first_order_designs_are_unstable_on_the_emulated_plant(double_support) -> None:
    links, models = double_support
    chain = _gain({**CLOSED_CHAIN, **FIRST_ORDER}, links, SupportState.DOUBLE)
    stuck = loop_modes(models[Friction.STUCK], closed_loop(models[Friction.STUCK], chain))
    assert stuck.oscillatory > 1.02 and 2.4 < stuck.oscillatory_hz < 2.9, stuck.text()
    sliding = loop_modes(models[Friction.SLIDING], closed_loop(models[Friction.SLIDING], chain))
    assert sliding.radius > 2 and sliding.radius_hz == pytest.approx(100.0), sliding.text()
    paper = _gain({**PAPER, **FIRST_ORDER}, links, SupportState.DOUBLE)
    paper_stuck = loop_modes(models[Friction.STUCK], closed_loop(models[Friction.STUCK], paper))
    assert paper_stuck.oscillatory > 1.01, paper_stuck.text()


def test_ours_is_stable_on_the_emulated_plant_in_double_support(double_support) -> None:
    links, models = double_support
    ours = _gain({}, links, SupportState.DOUBLE)
    assert ours.motor_velocity_increment_gain is not None  # the configuration's default
    for friction, model in models.items():
        modes = loop_modes(model, closed_loop(model, ours))
        assert modes.oscillatory < 0.998, (friction, modes.text())
        assert modes.radius < 1 + 1e-6, (friction, modes.text())


def test_ours_is_stable_on_the_emulated_plant_on_one_foot() -> None:
    legs = LegModel(URDF_PATH.read_text())
    target = PostureTarget((0, 0.1278, 0), (0, -0.1278, 0.05), (0, 0.1278), 0.87)
    angles = solve_posture(legs, target, READY).leg_angles_rad
    robot = settled_robot(angles, SupportState.LEFT, seconds=2.0)
    ours = _gain({}, robot.plant.link_angle_rad, SupportState.LEFT)
    for friction in Friction:
        model = linearise(robot, PERIOD_S, friction)
        modes = loop_modes(model, closed_loop(model, ours))
        assert modes.oscillatory < 0.9998, (friction, modes.text())
        # the servo's integrals against the stuck rotors drift at e-folding times of ~100 s
        assert modes.radius < 1 + 1e-4, (friction, modes.text())
