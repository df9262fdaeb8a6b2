"""The gravity compensator (5)-(8) on the emulated robot: its sign against MuJoCo's spring
torques, and standing still with the GC feed-forward (motors commanded to theta_d + ug).

What limits "the link angles match the desired ones": the GC makes the gear spring carry the
load at the desired angles; the emulated H54 servo adds its own static lag tau / (Kpp kv)
(785 N m/rad for the stock gains: ~40 mrad at the knee standing, ~80 mrad at the hip roll on
one foot), which only its weak velocity-loop integral (Ti = 15 s) winds out. So the link
errors decay with a ~15 s time constant; after 60 s they are about 1 mrad (stated tolerance:
2 mrad). The fast tests use a servo integral 10 x stronger (Ti = 1.5 s) in double support, or
compare torques rather than angles.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from controller.humanoid import (
    LAB_WALK_INIT_LEG_ANGLES_RAD,
    WALKING_READY_LEG_ANGLES_RAD,
    HumanoidLegGravity,
    LegModel,
    PostureTarget,
    SupportState,
    solve_posture,
)
from sim_backend.dynamixel.device import H54Device
from sim_backend.humanoid.params import RobotTruthParams, leg_eeprom_overrides
from sim_backend.humanoid.robot import EmulatedRobot
from sim_backend.servo import RAD_PER_PULSE, H54ServoParams

URDF_PATH = Path(__file__).resolve().parents[2] / "hil" / "data" / "robots" / "dyros_jet.urdf"
READY = np.array(WALKING_READY_LEG_ANGLES_RAD)
K_NM_PER_RAD = 2000.0
FAST_INTEGRAL = RobotTruthParams(servo=H54ServoParams(velocity_integral_time_s=1.5))


@pytest.fixture(scope="module")
def urdf_text() -> str:
    return URDF_PATH.read_text()


@pytest.fixture(scope="module")
def leg_model(urdf_text: str) -> LegModel:
    return LegModel(urdf_text)


def posture(leg_model: LegModel, support: SupportState) -> np.ndarray:
    """Double support: the walking-ready posture. Single support: CoM over the stance sole
    centre, the other foot lifted 8 cm (a 3 cm lift touches down while the hip roll sags)."""
    if support is SupportState.DOUBLE:
        return READY
    left_z, right_z, com_y = (
        (0.0, 0.08, 0.1278)
        if support is SupportState.LEFT
        else (
            0.08,
            0.0,
            -0.1278,
        )
    )
    target = PostureTarget((0, 0.1278, left_z), (0, -0.1278, right_z), (0, com_y), 0.87)
    return solve_posture(leg_model, target, np.array(LAB_WALK_INIT_LEG_ANGLES_RAD)).leg_angles_rad


def stand(
    urdf_text: str,
    leg_model: LegModel,
    support: SupportState,
    duration_s: float,
    *,
    with_gc: bool = True,
    truth: RobotTruthParams | None = None,
) -> tuple[EmulatedRobot, np.ndarray, np.ndarray]:
    """Place the robot at the posture, command theta_d (+ ug), run; (robot, theta_d, tau_g)."""
    angles = posture(leg_model, support)
    tau = HumanoidLegGravity(leg_model, support).gravity_torque(angles)
    goal = angles + (tau / K_NM_PER_RAD if with_gc else 0.0)
    devices = [H54Device(i + 1, eeprom_overrides=leg_eeprom_overrides()) for i in range(12)]
    robot = EmulatedRobot(
        urdf_text, devices, truth=truth, initial_leg_angles_rad=angles, support_feet=support.feet
    )
    for index, device in enumerate(devices):
        device.set_item("Torque Enable", 1)
        device.set_item("Goal Position", round(goal[index] / RAD_PER_PULSE))
    robot.advance(duration_s)
    assert all(device.hardware_error_status == 0 for device in devices)
    in_contact = tuple(side for side in (0, 1) if robot.plant.sole_in_contact(side))
    assert in_contact == support.feet  # still in the support state we set out to test
    return robot, angles, tau


def internal_force_torques(leg_model: LegModel, link_angles: np.ndarray, rotation: np.ndarray):
    """The 12 x 6 leg-joint torques of internal wrenches in double support: a wrench w on the
    left sole and -w on the right (both at the world origin, so that they cancel on the
    robot). Double support is statically indeterminate by exactly these six directions: which
    of them the standing robot carries depends on how it settled (sticking soles keep it)."""
    model, data = leg_model.model, leg_model.data
    q = leg_model.configuration(link_angles, base_rotation=rotation)
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    left, right = (
        pin.getFrameJacobian(model, data, leg_model.sole_frame_ids[side], pin.ReferenceFrame.WORLD)
        for side in (0, 1)
    )
    return (left - right)[:, leg_model.leg_v_index].T


def modulo_internal_force(
    leg_model: LegModel, torque: np.ndarray, link_angles: np.ndarray, rotation: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(the part of a leg torque difference no internal wrench explains, the internal part)."""
    basis = internal_force_torques(leg_model, link_angles, rotation)
    wrench, *_ = np.linalg.lstsq(basis, torque, rcond=None)
    internal = basis @ wrench
    return torque - internal, internal


@pytest.mark.parametrize("support", [SupportState.LEFT, SupportState.RIGHT])
def test_gc_sign_against_the_plant_spring_torques(
    urdf_text: str, leg_model: LegModel, support: SupportState
) -> None:
    """Single support is statically determinate: at rest every gear spring carries exactly the
    holding torque. tau_g of (5), evaluated at the plant's measured link angles and pelvis
    orientation, must equal K (theta_m - theta_j) (+ D ...) of each joint, sign included."""
    robot, _, _ = stand(urdf_text, leg_model, support, 4.0)
    plant = robot.plant
    gc = HumanoidLegGravity(leg_model, support)
    gc.set_base_rotation(plant.pelvis_rotation)
    predicted = gc.gravity_torque(plant.link_angle_rad)
    spring = plant.gear_torque_nm
    assert np.abs(spring).max() > 50.0  # a real load: the stance hip roll and knee
    assert np.abs(spring - predicted).max() < 0.25
    # the sign trap: the naive (5) (upward support force) is off by twice the torque
    assert np.abs(spring + predicted).max() > 100.0


def test_gc_split_against_the_plant_in_double_support(urdf_text: str, leg_model: LegModel) -> None:
    """Double support is statically indeterminate: the plant's spring torques may differ from
    the paper's mu split (5)-(7) by an internal force between the feet (the soles stick, so it
    stays wherever the settling and the servo lag left it), and by nothing else."""
    robot, _, _ = stand(urdf_text, leg_model, SupportState.DOUBLE, 4.0)
    plant = robot.plant
    gc = HumanoidLegGravity(leg_model, SupportState.DOUBLE)
    gc.set_base_rotation(plant.pelvis_rotation)
    angles = plant.link_angle_rad
    difference = plant.gear_torque_nm - gc.gravity_torque(angles)
    unexplained, internal = modulo_internal_force(
        leg_model, difference, angles, plant.pelvis_rotation
    )
    assert np.abs(unexplained).max() < 0.3
    assert np.abs(internal).max() < 6.0  # a few N m: far below the knees' 30 N m load
    assert abs(plant.gear_torque_nm[3]) > 25.0
    # the check can fail: a torque that is not an internal force (one knee loaded more) is
    # left unexplained
    lopsided = np.zeros(12)
    lopsided[3] = 1.0
    assert (
        np.abs(modulo_internal_force(leg_model, lopsided, angles, plant.pelvis_rotation)[0]).max()
        > 0.3
    )


@pytest.mark.slow  # 12 s of robot time, ~6 s of CPU
def test_standing_with_gc_double_support_fast_servo_integral(
    urdf_text: str, leg_model: LegModel
) -> None:
    """With the servo lag wound out quickly, the links sit at the desired angles with the GC, and
    without it every joint is off by its spring's deflection -tau_g / K (the knee ~16 mrad)."""
    robot, angles, tau = stand(urdf_text, leg_model, SupportState.DOUBLE, 6.0, truth=FAST_INTEGRAL)
    error = robot.plant.link_angle_rad - angles
    assert np.abs(error).max() < 1e-3  # 1 mrad (0.6 measured at 6 s, 0.04 at 10 s)
    assert robot.plant.pelvis_tilt_rad < 1e-3
    gc = HumanoidLegGravity(leg_model, SupportState.DOUBLE)
    gc.set_base_rotation(robot.plant.pelvis_rotation)
    # what the split (5)-(7) does not say is an internal force between the feet
    difference = robot.plant.gear_torque_nm - gc.gravity_torque(robot.plant.link_angle_rad)
    unexplained, _ = modulo_internal_force(
        leg_model, difference, robot.plant.link_angle_rad, robot.plant.pelvis_rotation
    )
    assert np.abs(unexplained).max() < 0.3
    robot, angles, tau = stand(
        urdf_text, leg_model, SupportState.DOUBLE, 6.0, with_gc=False, truth=FAST_INTEGRAL
    )
    error = robot.plant.link_angle_rad - angles
    assert abs(error[3]) > 0.014
    # the sagittal joints within 2 mrad (the sagged posture loads the knees a little more);
    # sideways the sticking feet take part of the hips' load as an internal force, so the
    # springs carry tau_g modulo that force
    sagittal = [2, 3, 4, 8, 9, 10]  # hip pitch, knee, ankle pitch
    assert np.allclose(error[sagittal], -tau[sagittal] / K_NM_PER_RAD, atol=2e-3)
    plant = robot.plant
    gc.set_base_rotation(plant.pelvis_rotation)
    difference = plant.gear_torque_nm - gc.gravity_torque(plant.link_angle_rad)
    unexplained, _ = modulo_internal_force(
        leg_model, difference, plant.link_angle_rad, plant.pelvis_rotation
    )
    assert np.abs(unexplained).max() < 0.3


def test_default_posture_stands(urdf_text: str, leg_model: LegModel) -> None:
    """The walking-ready posture with the stock servos: the pelvis stays nearly level (the
    knees' servo lag tilts it by ~1.5 deg with the GC, more without) and nothing falls."""
    for with_gc, limit_rad in ((True, 0.03), (False, 0.06)):
        robot, _, _ = stand(urdf_text, leg_model, SupportState.DOUBLE, 3.0, with_gc=with_gc)
        assert robot.plant.pelvis_tilt_rad < limit_rad
        assert robot.plant.pelvis_position_m[2] > 0.82


@pytest.mark.slow
@pytest.mark.parametrize("support", list(SupportState))
def test_standing_with_gc_stock_servo(
    urdf_text: str, leg_model: LegModel, support: SupportState
) -> None:
    """The stock H54 servo (Ti = 15 s), 60 s of robot time (~25-35 s of wall time each)."""
    robot, angles, _ = stand(urdf_text, leg_model, support, 60.0)
    error = robot.plant.link_angle_rad - angles
    assert np.abs(error).max() < 2e-3
    assert robot.plant.pelvis_tilt_rad < 2e-3
