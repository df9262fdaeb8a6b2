"""The emulated fixed-base robot (sim_backend/fixed_base/) built from the URDF the controller's
model reads: placed at rest, each gear spring carries exactly the generalised gravity the
controller's pinocchio model computes (the two models share every figure: the rotors' 0.1 g
aside), each joint's gear is its actuator model's, and the tool touches the block where the
geometry says."""

from __future__ import annotations

from importlib import resources

import numpy as np
import pytest

from controller.fixed_base import FixedBaseModel
from sim_backend.fixed_base.params import FixedBaseTruthParams, model_gear_figures
from sim_backend.fixed_base.plant import FixedBasePlant
from sim_backend.spec import BlockSpec

URDF = resources.files("hil").joinpath("data", "robots", "two_link_arm.urdf").read_text()
MODELS = ("H54-200-S500-R", "H54-100-S500-R")
NAMES = ("shoulder", "elbow")


def plant(**kwargs: object) -> FixedBasePlant:
    truth = FixedBaseTruthParams()
    return FixedBasePlant(URDF, NAMES, truth.gears(MODELS), [78.5, 44.4], truth, **kwargs)  # type: ignore[arg-type]


@pytest.mark.parametrize("angles", [(0.0, 0.0), (0.4, -0.9), (-1.0, 1.2)])
def test_at_rest_each_gear_carries_the_controllers_gravity_torque(
    angles: tuple[float, float],
) -> None:
    emulated = plant()
    emulated.place_at(angles)
    np.testing.assert_allclose(emulated.link_angle_rad, angles, atol=1e-12)
    nominal = FixedBaseModel(URDF, NAMES).gravity_torque(angles)
    np.testing.assert_allclose(emulated.gear_torque_nm, nominal, rtol=2e-4, atol=1e-6)
    stiffness = [model_gear_figures(m).gear_stiffness_nm_per_rad for m in MODELS]
    np.testing.assert_allclose(emulated.deflection_rad, -emulated.gear_torque_nm / stiffness)


def test_each_joints_gear_is_its_actuator_models() -> None:
    h54, h54_100 = (model_gear_figures(m) for m in MODELS)
    assert h54.gear_stiffness_nm_per_rad == 2000.0 and h54.gear_damping_nms_per_rad == 100.0
    # the H54-100-S500-R: the H54-200's scaled by 25.3 / 44.7 N m (an assumption, params.py)
    assert h54_100.gear_stiffness_nm_per_rad == pytest.approx(2000.0 * 25.3 / 44.7)
    overridden = FixedBaseTruthParams(gear_stiffness_nm_per_rad=(1500.0, 900.0)).gears(MODELS)
    assert [g.gear_stiffness_nm_per_rad for g in overridden] == [1500.0, 900.0]
    with pytest.raises(ValueError, match="one per joint"):
        FixedBaseTruthParams(gear_stiffness_nm_per_rad=(1.0, 2.0, 3.0)).gears(MODELS)


def test_the_tool_touches_the_block_and_the_force_is_measured() -> None:
    # the tool at (0.55, 0, 0.3) with the arm horizontal; a block whose top is 1 cm below it
    block = BlockSpec((0.55, 0.0, 0.3 - 0.02 - 0.01 - 0.05), (0.1, 0.1, 0.1))
    emulated = plant(tool=("tool", (0.0, 0.0, 0.0), 0.02), block=block)
    emulated.place_at((0.0, 0.0))
    np.testing.assert_allclose(emulated.tool_position_m, (0.55, 0.0, 0.3), atol=1e-12)
    assert emulated.contact_force_n() == 0.0
    emulated.place_at((-0.05, 0.0))  # the tool 2.75 cm lower: 1.75 cm into the block
    for _ in range(5):
        emulated.step()
    assert emulated.contact_force_n() > 10.0
