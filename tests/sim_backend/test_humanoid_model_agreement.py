"""One robot description, two models: MuJoCo (emulator) and pinocchio (controller) agree.

Tolerances: both models are built from the same URDF numbers, so the rigid models agree to
round-off (1e-9 relative is asked; measured ~1e-15). The flexible MuJoCo model adds 12 rotors of
0.1 g each (1.2 g on 50 kg) and the reflected inertias; those are checked explicitly.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from controller.humanoid import LAB_WALK_INIT_UPPER_BODY_RAD as CONTROLLER_UPPER_BODY
from controller.humanoid import WALKING_READY_LEG_ANGLES_RAD, LegModel
from sim_backend.humanoid.mjcf import MOTOR_SUFFIX, ROTOR_MASS_KG, build_mjcf
from sim_backend.humanoid.params import LAB_WALK_INIT_UPPER_BODY_RAD as EMULATOR_UPPER_BODY
from sim_backend.humanoid.params import LEG_JOINT_NAMES, RobotTruthParams
from sim_backend.urdf_description import parse_urdf

URDF_PATH = Path(__file__).resolve().parents[2] / "hil" / "data" / "robots" / "dyros_jet.urdf"
RNG_SEED = 20180521


@pytest.fixture(scope="module")
def urdf_text() -> str:
    return URDF_PATH.read_text()


@pytest.fixture(scope="module")
def leg_model(urdf_text: str) -> LegModel:
    return LegModel(urdf_text)


def mujoco_model(urdf_text: str, rigid: bool, **truth: object) -> mujoco.MjModel:
    params = RobotTruthParams(**truth)  # type: ignore[arg-type]
    return mujoco.MjModel.from_xml_string(build_mjcf(parse_urdf(urdf_text), params, rigid=rigid))


def postures() -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """(leg angles, base position, base rotation): the walking-ready posture upright, and three
    random ones with a turned base."""
    rng = np.random.default_rng(RNG_SEED)
    cases = [(np.array(WALKING_READY_LEG_ANGLES_RAD), np.array([0.0, 0.0, 0.87]), np.eye(3))]
    for _ in range(3):
        angles = np.array(WALKING_READY_LEG_ANGLES_RAD) + rng.uniform(-0.5, 0.5, 12)
        cases.append((angles, rng.uniform(-1, 1, 3), pin.exp3(rng.uniform(-0.6, 0.6, 3))))
    return cases


def set_rigid_state(model: mujoco.MjModel, data: mujoco.MjData, angles, position, rotation):
    data.qpos[:3] = position
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(rotation).ravel())
    data.qpos[3:7] = quat
    for index, name in enumerate(LEG_JOINT_NAMES):
        data.qpos[model.jnt_qposadr[model.joint(name).id]] = angles[index]
    data.qvel[:] = 0.0
    mujoco.mj_forward(model, data)


def leg_dofs(model: mujoco.MjModel, suffix: str = "") -> np.ndarray:
    return np.array([model.jnt_dofadr[model.joint(name + suffix).id] for name in LEG_JOINT_NAMES])


def test_same_upper_body_posture_on_both_sides() -> None:
    assert dict(CONTROLLER_UPPER_BODY) == dict(EMULATOR_UPPER_BODY)


def test_total_mass(urdf_text: str, leg_model: LegModel) -> None:
    rigid = mujoco_model(urdf_text, rigid=True)
    flexible = mujoco_model(urdf_text, rigid=False)
    assert rigid.body_subtreemass[1] == pytest.approx(leg_model.total_mass_kg, abs=1e-12)
    assert flexible.body_subtreemass[1] == pytest.approx(
        leg_model.total_mass_kg + 12 * ROTOR_MASS_KG, abs=1e-12
    )


@pytest.mark.parametrize("case", range(4))
def test_mass_matrix_gravity_and_com_agree(urdf_text: str, leg_model: LegModel, case: int) -> None:
    angles, position, rotation = postures()[case]
    model = mujoco_model(urdf_text, rigid=True)
    data = mujoco.MjData(model)
    set_rigid_state(model, data, angles, position, rotation)
    q = leg_model.configuration(angles, position, rotation)
    mujoco_inertia = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, mujoco_inertia)
    pin_inertia = pin.crba(leg_model.model, leg_model.data, q)
    pin_inertia = np.triu(pin_inertia) + np.triu(pin_inertia, 1).T
    legs_mj, legs_pin = leg_dofs(model), leg_model.leg_v_index
    scale = np.abs(pin_inertia).max()
    leg_block = mujoco_inertia[np.ix_(legs_mj, legs_mj)] - pin_inertia[np.ix_(legs_pin, legs_pin)]
    assert np.abs(leg_block).max() < 1e-9 * scale
    # gravity torques on the leg joints: MuJoCo's bias force at rest vs pinocchio's RNEA
    gravity = pin.computeGeneralizedGravity(leg_model.model, leg_model.data, q)
    assert np.abs(data.qfrc_bias[legs_mj] - gravity[legs_pin]).max() < 1e-9 * 500
    # the whole robot's CoM
    com = pin.centerOfMass(leg_model.model, leg_model.data, q)
    assert np.abs(data.subtree_com[model.body("base_link").id] - com).max() < 1e-12
    if case == 0:
        # base upright: MuJoCo's free joint (linear velocity in world axes) and pinocchio's
        # free flyer (in pelvis axes) use the same coordinates, so the whole 18 x 18 agrees
        assert np.abs(mujoco_inertia - pin_inertia).max() < 1e-9 * scale
        assert np.abs(data.qfrc_bias - gravity).max() < 1e-9 * 500


def test_flexible_joints_wrap_the_rigid_model(urdf_text: str) -> None:
    """With x = (base, theta_m, deflection) and theta_j = theta_m + deflection, the flexible
    model's inertia is T^T M_rigid T plus the reflected inertia on each motor (and the rotors'
    0.1 g); its gravity on the motor and on the deflection coordinate is the link's."""
    angles, position, rotation = postures()[1]
    rigid = mujoco_model(urdf_text, rigid=True)
    rigid_data = mujoco.MjData(rigid)
    set_rigid_state(rigid, rigid_data, angles, position, np.eye(3))
    flexible = mujoco_model(urdf_text, rigid=False, motor_reflected_inertia_kg_m2=0.25)
    data = mujoco.MjData(flexible)
    data.qpos[:3] = position
    data.qpos[3:7] = (1, 0, 0, 0)
    deflection = np.linspace(-0.01, 0.01, 12)
    motors, gears = leg_dofs(flexible, MOTOR_SUFFIX), leg_dofs(flexible)
    for index, name in enumerate(LEG_JOINT_NAMES):
        data.qpos[flexible.jnt_qposadr[flexible.joint(name + MOTOR_SUFFIX).id]] = (
            angles[index] - deflection[index]
        )
        data.qpos[flexible.jnt_qposadr[flexible.joint(name).id]] = deflection[index]
    mujoco.mj_forward(flexible, data)
    m_rigid = np.zeros((rigid.nv, rigid.nv))
    mujoco.mj_fullM(rigid, rigid_data, m_rigid)
    m_flex = np.zeros((flexible.nv, flexible.nv))
    mujoco.mj_fullM(flexible, data, m_flex)
    # T maps (base 6, motors 12, deflections 12) -> (base 6, links 12)
    order = np.r_[np.arange(6), motors, gears]
    t = np.zeros((18, 30))
    t[:6, :6] = np.eye(6)
    t[6:, 6:18] = np.eye(12)
    t[6:, 18:] = np.eye(12)
    legs_rigid = leg_dofs(rigid)
    m_rigid_ordered = m_rigid[
        np.ix_(np.r_[np.arange(6), legs_rigid], np.r_[np.arange(6), legs_rigid])
    ]
    expected = t.T @ m_rigid_ordered @ t
    expected[6:18, 6:18] += 0.25 * np.eye(12)  # armature on the motor hinges
    difference = m_flex[np.ix_(order, order)] - expected
    # what is left is the rotors' own 0.1 g each: 12 x 0.1 g on the base's mass, and at most
    # m r^2 ~ 1e-4 kg x 1 m^2 elsewhere; far below the 0.25 kg m^2 reflected inertia
    assert np.allclose(difference[:3, :3], 12 * ROTOR_MASS_KG * np.eye(3), atol=1e-12)
    assert np.abs(difference).max() <= 12 * ROTOR_MASS_KG + 1e-12
    assert np.abs(difference[6:, 6:]).max() < 5 * ROTOR_MASS_KG  # <= 5 rotors, under 1 m
    # gravity: equal on each joint's motor and deflection coordinates, equal to the rigid link's
    # (the rotors' 0.1 g add at most 1e-3 N m)
    gravity_rigid = rigid_data.qfrc_bias[legs_rigid]
    assert np.allclose(data.qfrc_bias[motors], data.qfrc_bias[gears], atol=2e-3)
    assert np.allclose(data.qfrc_bias[gears], gravity_rigid, atol=2e-3)


def test_truth_overrides_change_the_emulated_robot_only(urdf_text: str, leg_model: LegModel):
    """The truth differs from the nominal controller model when a run says so."""
    scaled = mujoco_model(urdf_text, rigid=True, mass_scale=1.1)
    assert scaled.body_subtreemass[1] == pytest.approx(1.1 * leg_model.total_mass_kg)
    offset = (0.02, -0.01, 0.0)
    shifted = mujoco_model(urdf_text, rigid=True, com_offset_m=offset)
    plain = mujoco_model(urdf_text, rigid=True)
    com = []
    for model in (shifted, plain):
        data = mujoco.MjData(model)
        data.qpos[3] = 1.0
        mujoco.mj_forward(model, data)
        com.append(data.subtree_com[1].copy())
    torso = 14.09938  # kg, WaistYaw_Link in the URDF
    assert np.allclose(com[0] - com[1], np.array(offset) * torso / leg_model.total_mass_kg)
    stiff = mujoco_model(urdf_text, rigid=False, gear_stiffness_nm_per_rad=2500.0)
    assert stiff.jnt_stiffness[stiff.joint("L_KneePitch").id] == 2500.0
    # the controller's nominal model is untouched: it reads the URDF, not the truth
    assert leg_model.total_mass_kg == pytest.approx(49.95809)


def test_description_file_credits_its_source_and_fixes_the_limits(urdf_text: str) -> None:
    assert "BSD 2-Clause" in urdf_text and "Suhan Park" in urdf_text
    assert "psh117/dyros_jet" in urdf_text
    assert "/work/" not in urdf_text and "shared" not in urdf_text
    root = ET.fromstring(urdf_text)
    for name in LEG_JOINT_NAMES:
        limit = root.find(f"joint[@name='{name}']/limit")
        assert float(limit.get("effort")) == 44.7 and float(limit.get("velocity")) == 3.47
    assert (
        root.find("link[@name='L_HipPitch_Link']/inertial/origin").get("xyz").startswith("0.12203")
    )
    assert (
        root.find("link[@name='R_HipPitch_Link']/inertial/origin").get("xyz").startswith("0.11203")
    )
    description = parse_urdf(urdf_text)
    for foot in ("L_AnkleRoll_Link", "R_AnkleRoll_Link"):
        (box,) = description.links[foot].boxes
        assert np.allclose(box.centre_m, [0.01, 0, -0.095]) and np.allclose(
            box.size_m, [0.30, 0.17, 0.02]
        )
