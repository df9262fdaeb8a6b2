"""An object on the emulated humanoid's floor: a rigid box a sole lands on at the box's height."""

from __future__ import annotations

import numpy as np
import pytest

from controller.humanoid import WALKING_READY_LEG_ANGLES_RAD
from hil.config import load_config, robot_description_text
from sim_backend.humanoid.plant import HumanoidPlant
from sim_backend.spec import FloorBox

HEIGHT_M = 0.015


@pytest.fixture(scope="module")
def urdf_text() -> str:
    return robot_description_text(load_config(robot="dyros-jet"))


def test_a_floor_box_refuses_nonsense() -> None:
    with pytest.raises(ValueError, match="size_m"):
        FloorBox((0.0, 0.0), (0.3, 0.2, 0.0))
    with pytest.raises(ValueError, match="centre_m"):
        FloorBox((0.0, float("nan")), (0.3, 0.2, 0.01))


def test_the_right_sole_lands_on_the_box_at_its_height(urdf_text: str) -> None:
    """The robot standing, lifted so that its soles hang 4 mm above the box's top; the box lies
    under the right sole only. Falling 4 mm takes 29 ms (sqrt(2 h / g)): after 60 ms the right
    sole touches the box, at the box's top, and the left sole (HEIGHT_M + 4 mm above the floor)
    nothing yet."""
    plant = HumanoidPlant(urdf_text)
    plant.place_standing(WALKING_READY_LEG_ANGLES_RAD)
    ankle = plant.ft_sensor_pose(1)[0]  # the sole's centre is 0.01 m ahead: the box is 0.34 long
    box = FloorBox((float(ankle[0]), float(ankle[1])), (0.34, 0.21, HEIGHT_M))
    plant = HumanoidPlant(urdf_text, floor_boxes=(box,))
    plant.place_standing(WALKING_READY_LEG_ANGLES_RAD)
    plant.data.qpos[2] += HEIGHT_M + 0.004
    import mujoco

    mujoco.mj_forward(plant.model, plant.data)
    assert not plant.sole_contacts(0) and not plant.sole_contacts(1)
    for _ in range(round(0.06 / plant.physics_timestep_s)):
        plant.step()
    right = plant.sole_contacts(1)
    assert right, "the right sole did not land"
    assert {name for name, _ in right} == {"floor_box_0"}
    heights = np.array([point[2] for _, point in right])
    # MuJoCo's contact point lies midway in the penetration: the soft contact (20 ms time
    # constant) lets a 50 kg robot landing on one corner sink a few millimetres (measured: the
    # points at 13.0-14.4 mm); the floor would put them at 0
    assert np.all(np.abs(heights - HEIGHT_M) < 0.003), heights
    assert not plant.sole_contacts(0), "the left sole reached the floor under the box's height"
