"""Direction -1 and non-zero offsets, end to end on the wire: the emulated testbed mounts its
actuator and link encoder reversed and offset, the drivers are configured the same way, and the
SI values must come out as the plant's true angles.

The emulator runs in its own process (`emulator_process`), lock-step: its first SYNC samples
the plant at t = 0, where the state is known in closed form (the plant starts in static
balance, `TestbedPlant.settle_statically`): link angle theta0 and motor angle
theta0 + m g r cos(theta0) / K (the gear deflects by -m g r cos(theta0) / K under gravity).
A direction hard-wired to +1 anywhere on the way (node, driver, server) flips a sign or the
offset and misses these values by far more than the few counts allowed.

The same reversed mounting also comes from a configuration file, as a user writes it: once the
drivers built from the file (hil.wiring) against an emulator built here, once the emulator
built from the file against drivers built here. A direction or offset the configuration layer
drops on its way to either side (hard-wired to +1 between the file and the drivers, say)
then reads wrong angles too.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivers.canbus import LinkEncoderConfig
from drivers.dynamixel import DynamixelChainConfig, DynamixelJointConfig
from drivers.dynamixel_can_bus import CanChannelConfig, DynamixelCanBus, DynamixelCanBusConfig
from sim_backend.emulator_process import emulator_process
from sim_backend.plant import TestbedPlantParams as PlantParams
from sim_backend.server import EmulatedJointSpec, EmulatorSpec

pytestmark = pytest.mark.timeout(90)

THETA0_RAD = 0.15
MOTOR_DIRECTION, MOTOR_OFFSET_RAD = -1, 0.2
ENCODER_DIRECTION, ENCODER_OFFSET_RAD = -1, 0.3
PULSE_RAD = 2 * math.pi / 501_923  # H54-200-S500-R (e-Manual)
COUNT_RAD = 2 * math.pi / 983_040  # RLC2IC on MR075 (RLS data sheets)


def bus_for(endpoints: dict) -> DynamixelCanBus:
    config = DynamixelCanBusConfig(
        joint_names=("joint",),
        chains=(
            DynamixelChainConfig(
                port=endpoints["dynamixel_port"],
                baudrate=endpoints["baudrate"],
                joints=(
                    DynamixelJointConfig(
                        dxl_id=1,
                        name="joint",
                        direction=MOTOR_DIRECTION,
                        offset_rad=MOTOR_OFFSET_RAD,
                        min_position_rad=-1.5,
                        max_position_rad=1.5,
                    ),
                ),
                latency_timer_ms=50.0,  # lock-step: the emulator answers every request
            ),
        ),
        can_channels=(
            CanChannelConfig(
                "can0",
                endpoints["can"],
                encoders=(
                    LinkEncoderConfig(
                        5, direction=ENCODER_DIRECTION, offset_rad=ENCODER_OFFSET_RAD, name="joint"
                    ),
                ),
            ),
        ),
        link_timeout_s=0.2,
    )
    return DynamixelCanBus(config)


def emulator_spec_here() -> EmulatorSpec:
    return EmulatorSpec(
        joints=(
            EmulatedJointSpec(
                dxl_id=1,
                encoder_node_id=5,
                encoder_direction=ENCODER_DIRECTION,
                encoder_offset_rad=ENCODER_OFFSET_RAD,
                motor_direction=MOTOR_DIRECTION,
                motor_offset_rad=MOTOR_OFFSET_RAD,
            ),
        ),
        plant=PlantParams(initial_link_angle_rad=THETA0_RAD),
    )


def configuration_file():
    """The built-in testbed's file with the reversed, offset mounting (no force sensor: the
    emulator built here has none), read as `hil` reads a user's file."""
    from hil.config import default_config_text, parse_config

    text = default_config_text()
    for old, new in (
        ("encoder_offset_rad = 0.0 ", f"encoder_offset_rad = {ENCODER_OFFSET_RAD} "),
        ("\nencoder_direction = 1\n", f"\nencoder_direction = {ENCODER_DIRECTION}\n"),
        ("motor_offset_rad = 0.0 ", f"motor_offset_rad = {MOTOR_OFFSET_RAD} "),
        ("\nmotor_direction = 1\n", f"\nmotor_direction = {MOTOR_DIRECTION}\n"),
        ("node_id = 10 ", "node_id = 0 "),
        (
            "# plant = { load_mass_kg = 3.0 }",
            f"plant = {{ initial_link_angle_rad = {THETA0_RAD} }}",
        ),
    ):
        assert old in text, old
        text = text.replace(old, new, 1)
    return parse_config(text, "reversed.toml")


def test_reversed_and_offset_mountings_read_the_true_angles_and_move_the_right_way() -> None:
    with emulator_process(emulator_spec_here()) as emulator:
        _reads_true_angles_and_moves_up(bus_for(emulator.endpoints))


def test_the_mounting_of_a_configuration_file_reaches_the_drivers() -> None:
    from hil.wiring import Connection, make_bus

    config = configuration_file()
    with emulator_process(emulator_spec_here()) as emulator:
        connection = Connection.from_endpoints({**emulator.endpoints, "clock": "lockstep"}, config)
        _reads_true_angles_and_moves_up(make_bus(config, connection))


def test_the_mounting_of_a_configuration_file_reaches_the_emulated_devices() -> None:
    from hil.wiring.emulation import emulator_spec

    with emulator_process(emulator_spec(configuration_file())) as emulator:
        _reads_true_angles_and_moves_up(bus_for(emulator.endpoints))


def _reads_true_angles_and_moves_up(bus) -> None:
    plant = PlantParams(initial_link_angle_rad=THETA0_RAD)
    sag_rad = plant.gravity_m_s2 * plant.gravity_moment_kg_m * math.cos(THETA0_RAD)
    sag_rad /= plant.gear_stiffness_nm_per_rad
    with bus:
        first = bus.read()  # the first SYNC: the plant at t = 0
        assert first.motor_valid.all() and first.link_valid.all()
        assert abs(first.link_angle_rad[0] - THETA0_RAD) <= 2 * COUNT_RAD
        assert abs(first.motor_angle_rad[0] - (THETA0_RAD + sag_rad)) <= 2 * PULSE_RAD
        # A goal 0.1 rad up in the joint frame moves motor and link up.
        bus.enable()
        goal = first.motor_angle_rad + 0.1
        for _ in range(200):  # 1 s of plant time
            bus.write(goal)
            last = bus.read()
        bus.disable()
    moved = last.motor_angle_rad[0] - first.motor_angle_rad[0]
    assert 0.08 < moved < 0.11
    assert np.sign(last.link_angle_rad[0] - first.link_angle_rad[0]) == 1
    assert abs((last.link_angle_rad[0] - first.link_angle_rad[0]) - moved) < 0.01
