"""The emulated DYROS-JET hung by its pelvis from a gantry (`suspended`): the pelvis fixed in the
world, the feet clear of the floor, and the hanging statics of the gears.

Statics: at rest each gear carries the gravity torque of everything below it, so its deflection
is d = -g(q) / K, g(q) pinocchio's generalised gravity of the controller's model (built from
the same URDF; the emulator's 12 rotors of 0.1 g are not in it, 1e-4 of a leg's mass) at the
measured link angles. The knee is checked once more by hand: the moment of the shank and foot's
weight about the knee axis, from MuJoCo's kinematics (subtree mass and centre of mass).
After 1 s the legs still creep by ~1 mrad/s (the servos winding out their lag), which moves the
gear torques by far less than the tolerance (D times the deflection rate, ~0.01 N m).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from controller.humanoid import WALKING_READY_LEG_ANGLES_RAD, LegModel
from sim_backend.dynamixel.device import H54Device
from sim_backend.humanoid.mjcf import SUSPENSION_HEIGHT_M
from sim_backend.humanoid.params import (
    KNEE_INDICES,
    LEG_JOINT_NAMES,
    N_LEG_JOINTS,
    leg_eeprom_overrides,
)
from sim_backend.humanoid.plant import HumanoidPlant
from sim_backend.humanoid.robot import EmulatedRobot

URDF_PATH = Path(__file__).resolve().parents[2] / "hil" / "data" / "robots" / "dyros_jet.urdf"
READY = np.array(WALKING_READY_LEG_ANGLES_RAD)
K_NM_PER_RAD = 2000.0
HIP_PITCH_INDICES = (2, 8)
HANG_S = 1.0


@pytest.fixture(scope="module")
def urdf_text() -> str:
    return URDF_PATH.read_text()


@pytest.fixture(scope="module")
def hanging(urdf_text: str) -> tuple[EmulatedRobot, np.ndarray, np.ndarray]:
    """A suspended robot in the walking-ready posture, every servo on holding where it hangs,
    after HANG_S; (robot, pelvis position, pelvis rotation) at power-on."""
    devices = [H54Device(i + 1, eeprom_overrides=leg_eeprom_overrides()) for i in range(12)]
    robot = EmulatedRobot(urdf_text, devices, initial_leg_angles_rad=READY, suspended=True)
    position, rotation = robot.plant.pelvis_position_m, robot.plant.pelvis_rotation
    for device in devices:
        device.set_item("Torque Enable", 1)
    robot.advance(HANG_S)
    assert all(device.hardware_error_status == 0 for device in devices)
    return robot, position, rotation


def test_no_free_joint_and_the_motor_views_still_work(urdf_text: str) -> None:
    plant = HumanoidPlant(urdf_text, suspended=True)
    model = plant.model
    assert model.njnt == 2 * N_LEG_JOINTS  # a motor and a gear hinge per leg joint, nothing else
    assert model.nq == model.nv == 2 * N_LEG_JOINTS
    assert not any(model.jnt_type == mujoco.mjtJoint.mjJNT_FREE)
    plant.hang(READY)
    angles, velocities = plant.motor_state_arrays()
    assert np.shares_memory(angles, plant.data.qpos)  # still views, now from address 0
    assert np.shares_memory(velocities, plant.data.qvel)
    np.testing.assert_array_equal(angles, READY)
    np.testing.assert_array_equal(plant.link_angle_rad, READY)  # hung without deflection
    np.testing.assert_allclose(plant.pelvis_position_m, (0.0, 0.0, SUSPENSION_HEIGHT_M))
    with pytest.raises(ValueError, match="hang"):
        plant.place_standing(READY)
    with pytest.raises(ValueError, match="place_standing"):
        HumanoidPlant(urdf_text).hang(READY)


def test_straight_legs_clear_the_floor(urdf_text: str) -> None:
    """The soles' undersides at least 0.2 m above the floor with the legs straight (the lowest
    the feet hang)."""
    plant = HumanoidPlant(urdf_text, suspended=True)
    plant.hang(np.zeros(N_LEG_JOINTS))
    for side in (0, 1):
        for geom in plant._sole_geoms[side]:
            corners = (
                np.array([(x, y, -1.0) for x in (-1.0, 1.0) for y in (-1.0, 1.0)])
                * plant.model.geom_size[geom]
            )
            world = (
                plant.data.geom_xpos[geom] + corners @ plant.data.geom_xmat[geom].reshape(3, 3).T
            )
            assert world[:, 2].min() > 0.2


def test_the_pelvis_stays_fixed(hanging) -> None:
    robot, position, rotation = hanging
    plant = robot.plant
    np.testing.assert_allclose(position, (0.0, 0.0, SUSPENSION_HEIGHT_M))
    np.testing.assert_allclose(rotation, np.eye(3))
    np.testing.assert_allclose(plant.pelvis_position_m, position, atol=1e-12)
    np.testing.assert_allclose(plant.pelvis_rotation, rotation, atol=1e-12)
    assert plant.pelvis_tilt_rad == pytest.approx(0.0, abs=1e-12)
    assert plant.pelvis_quaternion_wxyz == pytest.approx((1.0, 0.0, 0.0, 0.0), abs=1e-12)


def test_the_soles_touch_nothing(hanging) -> None:
    robot = hanging[0]
    plant = robot.plant
    assert plant.data.ncon == 0
    for side in (0, 1):
        assert not plant.sole_in_contact(side)
        assert plant.sole_contacts(side) == []
        force, moment = robot.foot_wrench(side)
        np.testing.assert_allclose(force, 0.0, atol=1e-9)
        np.testing.assert_allclose(moment, 0.0, atol=1e-9)


def test_the_gears_carry_the_legs_weight(hanging, urdf_text: str) -> None:
    plant = hanging[0].plant
    assert np.abs(plant.link_velocity_rad_s).max() < 5e-3  # hung still (module docstring)
    leg_model = LegModel(urdf_text)
    q = leg_model.configuration(plant.link_angle_rad)  # the pelvis upright, as hung
    gravity = pin.computeGeneralizedGravity(leg_model.model, leg_model.data, q)
    expected = -gravity[leg_model.leg_v_index] / K_NM_PER_RAD
    deflection = plant.deflection_rad
    for joint in KNEE_INDICES + HIP_PITCH_INDICES:
        assert abs(gravity[leg_model.leg_v_index][joint]) > 5.0  # a load worth checking
        assert deflection[joint] == pytest.approx(expected[joint], rel=0.02), LEG_JOINT_NAMES[joint]
    # every joint, the unloaded ones (hip yaw, ankle roll: ~0) included
    np.testing.assert_allclose(deflection, expected, rtol=0.02, atol=0.02 / K_NM_PER_RAD)


def test_the_knee_by_hand(hanging) -> None:
    """K d at the knee = the moment about its axis of the weight of the links below it."""
    plant = hanging[0].plant
    model, data = plant.model, mujoco.MjData(plant.model)
    data.qpos[:] = plant.data.qpos
    mujoco.mj_forward(model, data)
    g = plant.params.gravity_m_s2
    for joint in KNEE_INDICES:
        hinge = model.joint(LEG_JOINT_NAMES[joint]).id  # the gear hinge, into the shank
        shank = model.jnt_bodyid[hinge]
        lever = data.subtree_com[shank] - data.xanchor[hinge]
        weight = np.array([0.0, 0.0, -model.body_subtreemass[shank] * g])
        gravity_moment = float(data.xaxis[hinge] @ np.cross(lever, weight))
        # the gear holds the shank: its torque on the link, -K d, cancels gravity's moment
        held = -K_NM_PER_RAD * plant.deflection_rad[joint]
        assert held == pytest.approx(-gravity_moment, rel=0.02)
        assert abs(gravity_moment) > 5.0


def test_the_emulator_spec_hangs_it() -> None:
    """EmulatedHumanoid.build passes HumanoidSpec.suspended to the plant."""
    from hil.config import load_config
    from hil.wiring.emulation import emulator_spec
    from sim_backend.humanoid.hardware import EmulatedHumanoid

    spec = emulator_spec(load_config(robot="dyros-jet"))
    assert spec.humanoid is not None and not spec.humanoid.suspended
    hung = dataclasses.replace(spec, humanoid=dataclasses.replace(spec.humanoid, suspended=True))
    plant = EmulatedHumanoid.build(hung).robot.plant
    assert plant.suspended
    assert plant.model.nq == 2 * N_LEG_JOINTS
    np.testing.assert_array_equal(plant.link_angle_rad, spec.humanoid.initial_leg_angles_rad)
