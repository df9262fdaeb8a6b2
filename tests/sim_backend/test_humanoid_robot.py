"""The emulated DYROS-JET: placement, foot sensors, per-joint firmware and protection, pushes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from controller.humanoid import (
    LAB_WALK_INIT_LEG_ANGLES_RAD,
    WALKING_READY_LEG_ANGLES_RAD,
    FootWrench,
    HumanoidLegGravity,
    LegModel,
    PostureTarget,
    SupportState,
    solve_posture,
    zmp_from_foot_wrenches,
)
from sim_backend.dynamixel.device import H54Device
from sim_backend.humanoid.params import (
    KNEE_INDICES,
    RobotTruthParams,
    leg_eeprom_overrides,
)
from sim_backend.humanoid.robot import EmulatedRobot, PelvisPush
from sim_backend.servo import OVERLOAD_BIT, RAD_PER_PULSE, H54ServoParams
from sim_backend.testbed import Mounting

URDF_PATH = Path(__file__).resolve().parents[2] / "hil" / "data" / "robots" / "dyros_jet.urdf"
READY = np.array(WALKING_READY_LEG_ANGLES_RAD)
K_NM_PER_RAD = 2000.0
WEIGHT_N = 49.95809 * 9.81


@pytest.fixture(scope="module")
def urdf_text() -> str:
    return URDF_PATH.read_text()


@pytest.fixture(scope="module")
def leg_model(urdf_text: str) -> LegModel:
    return LegModel(urdf_text)


def build_robot(
    urdf_text: str,
    angles: np.ndarray,
    *,
    support_feet: tuple[int, ...] = (0, 1),
    eeprom: dict[str, int] | None = None,
    truth: RobotTruthParams | None = None,
    goal_rad: np.ndarray | None = None,
    mountings: list[Mounting] | None = None,
) -> tuple[EmulatedRobot, list[H54Device]]:
    overrides = leg_eeprom_overrides() if eeprom is None else eeprom
    devices = [H54Device(i + 1, eeprom_overrides=overrides) for i in range(12)]
    robot = EmulatedRobot(
        urdf_text,
        devices,
        truth=truth,
        initial_leg_angles_rad=angles,
        support_feet=support_feet,
        motor_mountings=mountings,
    )
    for index, device in enumerate(devices):
        device.set_item("Torque Enable", 1)
        if goal_rad is not None:
            mount = robot.mountings[index]
            device.set_item(
                "Goal Position", round(mount.to_device(goal_rad[index]) / RAD_PER_PULSE)
            )
    return robot, devices


def single_support_posture(leg_model: LegModel, lift_m: float = 0.08) -> np.ndarray:
    """Left foot on the ground, CoM over its sole centre, right foot lifted, pelvis upright."""
    target = PostureTarget((0, 0.1278, 0), (0, -0.1278, lift_m), (0, 0.1278), 0.87)
    return solve_posture(leg_model, target, np.array(LAB_WALK_INIT_LEG_ANGLES_RAD)).leg_angles_rad


def sensor_zmp(robot: EmulatedRobot) -> np.ndarray:
    wrenches = []
    for side in (0, 1):
        force, torque = robot.foot_wrench(side)
        position, rotation = robot.plant.ft_sensor_pose(side)
        wrenches.append(FootWrench(force, torque, position, rotation))
    return zmp_from_foot_wrenches(wrenches)


def test_placed_standing_flat_on_the_floor(urdf_text: str, leg_model: LegModel) -> None:
    tau = HumanoidLegGravity(leg_model, SupportState.DOUBLE).gravity_torque(READY)
    robot, _ = build_robot(urdf_text, READY, goal_rad=READY + tau / K_NM_PER_RAD)
    plant = robot.plant
    for side in (0, 1):
        _, rotation = plant.ft_sensor_pose(side)
        assert np.allclose(rotation, np.eye(3), atol=1e-9)  # soles flat
    # the sole's bottom (0.105 m below the ankle axis, the sensor origin) touches z = 0
    assert plant.ft_sensor_pose(0)[0][2] == pytest.approx(0.105, abs=1e-9)
    assert np.allclose(plant.deflection_rad, 0.0) and np.allclose(plant.link_angle_rad, READY)
    robot.advance(0.1)
    assert plant.sole_in_contact(0) and plant.sole_in_contact(1)
    assert plant.data.ncon == 8  # 4 corners per sole
    assert 0.0 < -plant.data.contact.dist.min() < 0.002  # soft contact: under 2 mm deep


def test_foot_sensors_carry_the_weight_and_give_the_zmp(urdf_text: str) -> None:
    """At rest the ground carries the weight, and the ZMP from the two F/T sensors is the CoM's
    ground projection (statics: no horizontal momentum change)."""
    robot, _ = build_robot(urdf_text, READY)
    robot.advance(1.5)
    forces = [robot.foot_wrench(side)[0] for side in (0, 1)]
    assert forces[0][2] > 0.3 * WEIGHT_N and forces[1][2] > 0.3 * WEIGHT_N
    assert forces[0][2] + forces[1][2] == pytest.approx(WEIGHT_N, rel=2e-3)
    com = robot.plant.centre_of_mass_m
    assert np.allclose(sensor_zmp(robot), com[:2], atol=2e-3)
    assert np.linalg.norm(robot.plant.link_velocity_rad_s) < 0.01


def test_stock_torque_limit_trips_the_stance_leg_on_one_foot(
    urdf_text: str, leg_model: LegModel
) -> None:
    """Per-joint overload protection: with the e-Manual's Torque Limit (620 = 48 N m) the stance
    hip roll and knee need ~62 N m on one foot; each sits at its cap and its own protection trips
    after the 1.5 s the firmware model waits (90 % of the cap); the other joints run on."""
    angles = single_support_posture(leg_model)
    tau = HumanoidLegGravity(leg_model, SupportState.LEFT).gravity_torque(angles)
    assert abs(tau[1]) > 55 and abs(tau[3]) > 55
    robot, devices = build_robot(
        urdf_text, angles, support_feet=(0,), eeprom={}, goal_rad=angles + tau / K_NM_PER_RAD
    )
    tripped_at: dict[int, float] = {}
    while robot.time_s < 2.2:
        robot.advance(0.01)
        for index, device in enumerate(devices):
            if device.hardware_error_status & OVERLOAD_BIT and index not in tripped_at:
                tripped_at[index] = robot.time_s
    assert set(tripped_at) == {1, 3}  # L hip roll, L knee
    assert all(1.5 <= t <= 2.0 for t in tripped_at.values())
    for index in (1, 3):
        assert not devices[index].torque_enabled
        assert robot.plant.motor_torque_nm[index] == 0.0
    assert all(devices[i].torque_enabled for i in range(12) if i not in (1, 3))


def test_raised_torque_limit_holds_one_foot(urdf_text: str, leg_model: LegModel) -> None:
    angles = single_support_posture(leg_model)
    tau = HumanoidLegGravity(leg_model, SupportState.LEFT).gravity_torque(angles)
    robot, devices = build_robot(
        urdf_text, angles, support_feet=(0,), goal_rad=angles + tau / K_NM_PER_RAD
    )
    robot.advance(2.5)
    assert all(device.hardware_error_status == 0 for device in devices)
    assert robot.plant.sole_in_contact(0) and not robot.plant.sole_in_contact(1)
    assert robot.plant.pelvis_position_m[2] > 0.75


def test_knee_servo_gain_from_its_register(urdf_text: str) -> None:
    robot, devices = build_robot(urdf_text, READY)
    for index, device in enumerate(devices):
        expected = 58 if index in KNEE_INDICES else 32
        assert device.item("Position P Gain") == expected
    knee = robot.firmware[3]
    assert knee._position_gain() == pytest.approx(10.0 * 58 / 32)  # 18.1 1/s, the lab's ~18
    assert robot.firmware[2]._position_gain() == pytest.approx(10.0)


def test_velocity_gain_follows_the_register_and_the_truth(urdf_text: str) -> None:
    servos = tuple(
        H54ServoParams(velocity_gain_nms_per_rad=100.0) if i == 0 else H54ServoParams()
        for i in range(12)
    )
    robot, devices = build_robot(urdf_text, READY, truth=RobotTruthParams(servo=servos))
    actuator = robot.plant.model.actuator("L_HipYaw_motor").id
    robot.step()
    assert robot.plant.model.actuator_gainprm[actuator, 0] == pytest.approx(100.0)
    devices[0].set_item("Velocity P Gain", 399 * 2)  # the host doubles the register
    robot.step()
    assert robot.plant.model.actuator_gainprm[actuator, 0] == pytest.approx(200.0)


def test_torque_off_and_reboot(urdf_text: str) -> None:
    """Torque off: the joint goes limp behind its dynamic brake; REBOOT: RAM defaults (the knee's
    P gain back to 32: the host must write it again) and the servo holds where it stands."""
    robot, devices = build_robot(urdf_text, READY)
    robot.advance(0.5)
    devices[3].set_item("Torque Enable", 0)
    robot.advance(0.3)
    assert robot.plant.motor_torque_nm[3] == 0.0
    assert abs(robot.plant.link_angle_rad[3] - READY[3]) > 0.02  # the left knee gave way
    devices[3].reboot(robot.time_s)
    assert devices[3].item("Position P Gain") == 32
    assert devices[3].item("Goal Position") == devices[3].item("Present Position")


def test_mounting_direction_is_undone_by_the_device_frame(urdf_text: str) -> None:
    mountings = [
        Mounting(direction=-1, offset_rad=0.1) if i == 3 else Mounting() for i in range(12)
    ]
    robot, devices = build_robot(urdf_text, READY, mountings=mountings)
    robot.advance(0.5)
    present = devices[3].item("Present Position") * RAD_PER_PULSE
    assert present == pytest.approx(-robot.plant.motor_angle_rad[3] + 0.1, abs=2 * RAD_PER_PULSE)
    assert robot.plant.pelvis_position_m[2] > 0.8  # still standing: the goal was where it stood


def test_push_on_the_pelvis(urdf_text: str, leg_model: LegModel) -> None:
    tau = HumanoidLegGravity(leg_model, SupportState.DOUBLE).gravity_torque(READY)
    robot, _ = build_robot(urdf_text, READY, goal_rad=READY + tau / K_NM_PER_RAD)
    robot.pushes.append(PelvisPush(start_s=0.5, duration_s=0.1, force_n=(150.0, 0.0, 0.0)))
    robot.advance(0.5)  # the scenario clock has not started: no push yet
    start = robot.plant.pelvis_position_m.copy()
    robot.start_scenario()
    peak = 0.0
    zmp_peak = 0.0
    while robot.scenario_time_s < 2.0:
        robot.advance(0.005)
        peak = max(peak, robot.plant.pelvis_position_m[0] - start[0])
        zmp_peak = max(zmp_peak, sensor_zmp(robot)[0])
    assert peak > 0.005  # pushed forward
    assert zmp_peak > 0.02  # the feet's pressure moved towards the toes
    assert robot.plant.pelvis_tilt_rad < 0.05 and robot.plant.pelvis_position_m[2] > 0.8
