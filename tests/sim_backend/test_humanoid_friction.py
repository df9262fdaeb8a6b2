"""The humanoid's per-joint gearbox friction laws and servo figures (RobotTruthParams).

A varying law's bound is what HumanoidPlant writes into MuJoCo's dof_frictionloss before each
step (sim_backend/friction.py): checked against friction.py's law evaluated by hand at the state
the step starts from. The robot is hung (suspended: no contact to disturb the legs) and driven
by velocity commands that swing the motors through the Stribeck speed; gravity loads the gears.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from hil.config.emulator_overrides import check_overrides
from sim_backend.dynamixel.device import H54Device
from sim_backend.friction import GearboxFrictionParams
from sim_backend.humanoid.mjcf import build_mjcf
from sim_backend.humanoid.params import (
    KNEE_INDICES,
    LAB_KNEE_POSITION_GAIN_REGISTER,
    N_LEG_JOINTS,
    RobotTruthParams,
    leg_eeprom_overrides,
)
from sim_backend.humanoid.plant import HumanoidPlant
from sim_backend.humanoid.robot import EmulatedRobot
from sim_backend.servo import H54ServoParams
from sim_backend.urdf_description import parse_urdf

URDF_PATH = Path(__file__).resolve().parents[2] / "hil" / "data" / "robots" / "dyros_jet.urdf"
HANG = np.array([0.0, 0.0, -0.4, 0.8, -0.4, 0.0, 0.0, 0.0, -0.4, 0.8, -0.4, 0.0])
LEFT, RIGHT = range(6), range(6, 12)
# the left leg Stribeck (F_c 2, F_s 3, w_s 0.1), the right leg load-dependent (F_c 1, mu 0.2)
MIXED = RobotTruthParams(
    gearbox_friction_model=("stribeck",) * 6 + ("load-dependent",) * 6,
    gearbox_coulomb_friction_nm=(2.0,) * 6 + (1.0,) * 6,
    gearbox_stribeck_friction_nm=(3.0,) * 6 + (0.0,) * 6,
    gearbox_stribeck_velocity_rad_s=(0.1,) * 6 + (0.05,) * 6,
    gearbox_load_friction_ratio=(0.0,) * 6 + (0.2,) * 6,
)


@pytest.fixture(scope="module")
def urdf_text() -> str:
    return URDF_PATH.read_text()


def drive(plant: HumanoidPlant, steps: int, check) -> None:
    """Swing every motor at up to 0.3 rad/s (kv 78.5, cap 48 N m), calling check(state before
    the step) after each step with the motor speeds and gear torques it started from."""
    kv, cap = np.full(N_LEG_JOINTS, 78.5), np.full(N_LEG_JOINTS, 48.0)
    phase = np.linspace(0.0, math.pi, N_LEG_JOINTS)
    for _ in range(steps):
        command = 0.3 * np.sin(2 * math.pi * 2.0 * plant.time_s + phase)
        plant.set_servos(command, cap, kv)
        speeds, torques = plant.motor_velocity_rad_s, plant.gear_torque_nm
        plant.step()
        check(speeds, torques)


def bounds(plant: HumanoidPlant) -> np.ndarray:
    return plant.model.dof_frictionloss[plant.motor_dof_indices].copy()


def test_stribeck_at_rest_is_breakaway(urdf_text: str) -> None:
    plant = HumanoidPlant(urdf_text, MIXED, suspended=True)
    plant.hang(HANG)  # at rest
    plant.set_servos(np.zeros(N_LEG_JOINTS), np.full(N_LEG_JOINTS, 48.0), np.full(12, 78.5))
    plant.step()
    written = bounds(plant)
    np.testing.assert_allclose(written[list(LEFT)], 2.0 + 3.0, rtol=1e-12)  # F_c + F_s
    np.testing.assert_allclose(written[list(RIGHT)], 1.0, rtol=1e-12)  # no load yet: F_c


def test_each_law_as_written(urdf_text: str) -> None:
    plant = HumanoidPlant(urdf_text, MIXED, suspended=True)
    plant.hang(HANG)
    seen = {"fast": 0, "slow": 0, "loaded": 0}

    def check(speeds: np.ndarray, torques: np.ndarray) -> None:
        written = bounds(plant)
        for joint in LEFT:  # F_c + F_s exp(-(w / w_s)^2), by hand
            expected = 2.0 + 3.0 * math.exp(-((speeds[joint] / 0.1) ** 2))
            assert written[joint] == pytest.approx(expected, rel=1e-12, abs=1e-12)
            seen["fast" if abs(speeds[joint]) > 0.2 else "slow"] += 1
        for joint in RIGHT:  # F_c + mu |tau_t|, by hand
            assert written[joint] == pytest.approx(1.0 + 0.2 * abs(torques[joint]), rel=1e-12)
            seen["loaded"] += abs(torques[joint]) > 3.0
        for joint in range(N_LEG_JOINTS):  # and friction.py's own law
            law = MIXED.gearbox_friction(joint)
            loss = law.loss_nm(float(speeds[joint]), float(torques[joint]))
            assert written[joint] == pytest.approx(loss, rel=1e-12, abs=1e-12)

    drive(plant, 600, check)
    assert min(seen.values()) > 100  # the laws were seen away from their constant parts


def test_load_dependent_grows_with_the_gear_torque(urdf_text: str) -> None:
    """Hung still, the right knee carries its shank (~6 N m), the hip yaw nothing."""
    plant = HumanoidPlant(urdf_text, MIXED, suspended=True)
    plant.hang(HANG)
    hold = np.zeros(N_LEG_JOINTS)
    for _ in range(500):
        plant.set_servos(hold, np.full(N_LEG_JOINTS, 48.0), np.full(N_LEG_JOINTS, 78.5))
        plant.step()
    torque = np.abs(plant.gear_torque_nm)
    written = bounds(plant)
    knee, hip_yaw = KNEE_INDICES[1], 6
    assert torque[knee] > 3.0 and torque[hip_yaw] < 0.1
    assert written[knee] > written[hip_yaw] + 0.2 * 2.9
    assert written[knee] == pytest.approx(1.0 + 0.2 * torque[knee], rel=1e-3)


def test_a_model_tuple_reaches_its_joints(urdf_text: str) -> None:
    """Only the right knee Stribeck: the other eleven keep the MJCF's constant 3.95 N m."""
    knee = KNEE_INDICES[1]
    models = ["coulomb-viscous"] * N_LEG_JOINTS
    models[knee] = "stribeck"
    extra = [0.0] * N_LEG_JOINTS
    extra[knee] = 2.0
    params = RobotTruthParams(gearbox_friction_model=models, gearbox_stribeck_friction_nm=extra)
    plant = HumanoidPlant(urdf_text, params, suspended=True)
    plant.hang(HANG)

    def check(speeds: np.ndarray, torques: np.ndarray) -> None:
        written = bounds(plant)
        others = [j for j in range(N_LEG_JOINTS) if j != knee]
        assert np.all(written[others] == 3.95)
        expected = 3.95 + 2.0 * math.exp(-((speeds[knee] / 0.05) ** 2))
        assert written[knee] == pytest.approx(expected, rel=1e-12)

    drive(plant, 100, check)
    assert params.gearbox_friction(knee).stribeck_nm == 2.0
    assert params.gearbox_friction(0).varies is False


def test_the_default_writes_nothing(urdf_text: str) -> None:
    plant = HumanoidPlant(urdf_text, suspended=True)
    plant.hang(HANG)
    drive(plant, 50, lambda speeds, torques: None)
    assert np.all(bounds(plant) == 3.95)


@pytest.mark.parametrize(
    ("overrides", "key"),
    [
        ({"gearbox_stribeck_friction_nm": 1.0}, "gearbox_stribeck_friction_nm"),
        (
            {"gearbox_friction_model": "stribeck", "gearbox_load_friction_ratio": 0.1},
            "gearbox_load_friction_ratio",
        ),
        (
            {"gearbox_friction_model": "load-dependent", "gearbox_stribeck_velocity_rad_s": 1.0},
            "gearbox_stribeck_velocity_rad_s",
        ),
        # a figure for all 12 where only some joints' law reads it
        (
            {
                "gearbox_friction_model": ["stribeck"] * 6 + ["coulomb-viscous"] * 6,
                "gearbox_stribeck_friction_nm": 1.0,
            },
            "gearbox_stribeck_friction_nm",
        ),
        ({"gearbox_friction_model": "bam"}, "gearbox_friction_model must be one of"),
        ({"gearbox_friction_model": ["stribeck"] * 11}, "gearbox_friction_model needs"),
        ({"gearbox_load_friction_ratio": -0.1}, "gearbox_load_friction_ratio"),
        ({"position_gain_per_s": [10.0] * 11}, "position_gain_per_s"),
        ({"velocity_integral_time_s": 0.0}, "velocity_integral_time_s"),
        ({"velocity_gain_nms_per_rad": -1.0}, "velocity_gain_nms_per_rad"),
    ],
)
def test_refused_naming_the_key(overrides: dict, key: str) -> None:
    with pytest.raises(ValueError, match=key):
        RobotTruthParams(**overrides)


def test_per_joint_servo_figures_reach_servo_params(urdf_text: str) -> None:
    gains = tuple(8.0 + i for i in range(N_LEG_JOINTS))
    servo = H54ServoParams(current_noise_a=0.0)
    params = RobotTruthParams(
        servo=servo,
        position_gain_per_s=list(gains),  # (a list, as TOML and JSON give it)
        velocity_gain_nms_per_rad=90.0,
    )
    for joint in range(N_LEG_JOINTS):
        figures = params.servo_params(joint)
        assert figures.position_gain_per_s == gains[joint]
        assert figures.velocity_gain_nms_per_rad == 90.0
        assert figures.velocity_integral_time_s == servo.velocity_integral_time_s  # not given
        assert figures.current_noise_a == 0.0  # the rest is the servo's
    assert RobotTruthParams().servo_params(3) == H54ServoParams()
    # the MJCF's kv and the firmware's decoded registers (Kpp scaled by Position P Gain 594)
    plant = HumanoidPlant(urdf_text, params, suspended=True)
    np.testing.assert_array_equal(plant.model.actuator_gainprm[plant.actuator_indices, 0], 90.0)
    devices = [H54Device(i + 1, eeprom_overrides=leg_eeprom_overrides()) for i in range(12)]
    robot = EmulatedRobot(
        urdf_text, devices, truth=params, initial_leg_angles_rad=HANG, suspended=True
    )
    for joint in range(N_LEG_JOINTS):
        register = LAB_KNEE_POSITION_GAIN_REGISTER if joint in KNEE_INDICES else 32
        registers = robot.firmware[joint].registers
        assert registers.position_gain_per_s == pytest.approx(gains[joint] * register / 32)
        assert registers.velocity_gain_nms_per_rad == pytest.approx(90.0)


def test_the_default_builds_the_same_mjcf(urdf_text: str) -> None:
    """The new keys at their defaults change nothing of the model (nor of the steps: the
    coulomb-viscous bound is the MJCF's constant, test_the_default_writes_nothing)."""
    description = parse_urdf(urdf_text)
    old_way = RobotTruthParams()
    explicit = RobotTruthParams(
        gearbox_friction_model="coulomb-viscous",
        gearbox_stribeck_friction_nm=0.0,
        gearbox_stribeck_velocity_rad_s=0.05,
        gearbox_load_friction_ratio=0.0,
        position_gain_per_s=None,
        velocity_gain_nms_per_rad=None,
        velocity_integral_time_s=None,
    )
    assert build_mjcf(description, explicit, suspended=False) == build_mjcf(description, old_way)
    assert build_mjcf(description, explicit, rigid=True) == build_mjcf(
        description, old_way, rigid=True
    )
    assert [explicit.servo_params(i) for i in range(12)] == [H54ServoParams()] * 12
    assert explicit.gearbox_friction(0) == GearboxFrictionParams("coulomb-viscous", 3.95)


def test_the_host_checks_the_servo_figures_ranges() -> None:
    check_overrides("plant", {"position_gain_per_s": [10.0] * 12, "velocity_gain_nms_per_rad": 80})
    check_overrides("plant", {"gearbox_friction_model": ["stribeck"] * 12})  # words: unjudged
    for key in ("position_gain_per_s", "velocity_gain_nms_per_rad", "velocity_integral_time_s"):
        with pytest.raises(ValueError, match=rf"plant\.{key}\[11\]"):
            check_overrides("plant", {key: [10.0] * 11 + [1.0e9]})
