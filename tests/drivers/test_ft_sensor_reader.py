"""The feet's force/torque sensors on CAN: the driver (drivers/canbus) against the emulated
CiA 404 six-channel nodes (sim_backend/canbus), in-process on python-can's `virtual` bus.

open() runs with the nodes served from a background thread (canopen's SDO client blocks); the
ticks are lock-step: send_sync() -> the test pumps the nodes -> collect().
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pytest

from drivers.canbus import CanDeviceError, LinkEncoderConfig, LinkReading
from drivers.canbus.config import ForceTorqueSensorConfig
from drivers.canbus.units import wrench_from_counts
from sim_backend.canbus import LinkEncoderNode
from sim_backend.canbus.ft_sensor_node import ForceTorqueSensorNode
from tests.support import can_rig
from tests.support.can_rig import TICK_S

pytestmark = pytest.mark.timeout(30)

SI_PER_COUNT = np.array([0.1, 0.1, 0.1, 0.01, 0.01, 0.01])  # the emulated sensor's EDS


class Wrench:
    """A mutable wrench the emulated sensor measures (force N, moment N m)."""

    def __init__(self, force: tuple[float, ...], torque: tuple[float, ...]) -> None:
        self.force = np.array(force, dtype=float)
        self.torque = np.array(torque, dtype=float)

    def __call__(self) -> tuple[np.ndarray, np.ndarray]:
        return self.force.copy(), self.torque.copy()


class Rig(can_rig.Rig):
    """The shared rig with the force/torque sensors on the reader; `tick(pump=False)` leaves the
    nodes unpumped (nothing answers the SYNC)."""

    def __init__(self, nodes: list, encoders: list, sensors: list) -> None:
        super().__init__(nodes, encoders, force_torque_sensors=sensors)

    def tick(self, pump: bool = True) -> LinkReading:  # type: ignore[override]
        self.now_s += TICK_S
        self.reader.send_sync()
        if pump:
            self.runner.pump(self.now_s)
        return self.reader.collect(0.004 if pump else 0.0)


@pytest.fixture
def rigs() -> Iterator[list[Rig]]:
    made: list[Rig] = []
    yield made
    for rig in made:
        rig.close()


def feet_rig(rigs: list[Rig], left: Wrench, right: Wrench) -> Rig:
    """Two link encoders and both feet's sensors on one bus, as on the robot."""
    nodes = [
        LinkEncoderNode(1, lambda: 0.25),
        LinkEncoderNode(2, lambda: -0.5),
        ForceTorqueSensorNode(21, left),
        ForceTorqueSensorNode(22, right),
    ]
    rig = Rig(
        nodes,
        [LinkEncoderConfig(1), LinkEncoderConfig(2)],
        [ForceTorqueSensorConfig(21, "left foot"), ForceTorqueSensorConfig(22, "right foot")],
    )
    rigs.append(rig)
    rig.open()
    return rig


def test_conversion_against_analysis() -> None:
    force, torque = wrench_from_counts(
        np.array([12, -45, 2457, 50, -1234, 1]),
        SI_PER_COUNT,
        np.array([0.0, 0.0, 1.0]),
        np.array([0.5, 0.0, 0.0]),
    )
    assert np.allclose(force, [1.2, -4.5, 244.7]) and np.allclose(torque, [0.0, -12.34, 0.01])


def test_both_feet_in_si_units_with_the_encoders(rigs: list[Rig]) -> None:
    left = Wrench((1.23, -4.5, 245.67), (0.5, -12.345, 0.01))
    right = Wrench((-20.0, 3.05, 230.0), (-7.5, 3.333, -0.2))
    rig = feet_rig(rigs, left, right)
    reading = rig.tick()
    assert reading.all_valid
    assert reading.angles_rad[0] == pytest.approx(0.25, abs=1e-5)
    names = [wrench.label for wrench in reading.wrenches]
    assert names == ["left foot", "right foot"]
    # 0.1 N and 0.01 N m per count, rounded half up
    assert np.allclose(reading.wrenches[0].force_n, [1.2, -4.5, 245.7], atol=1e-9)
    assert np.allclose(reading.wrenches[0].torque_nm, [0.5, -12.34, 0.01], atol=1e-9)
    assert np.allclose(reading.wrenches[1].force_n, [-20.0, 3.1, 230.0], atol=1e-9)
    assert np.allclose(reading.wrenches[1].torque_nm, [-7.5, 3.33, -0.2], atol=1e-9)
    assert np.array_equal(reading.wrenches[0].raw, [12, -45, 2457, 50, -1234, 1])
    # the next SYNC gets the new sample
    left.force[2] = 100.0
    assert reading.wrenches[0].age_s == 0.0
    assert rig.tick().wrenches[0].force_n[2] == pytest.approx(100.0)


def test_saturation_at_the_int16_range(rigs: list[Rig]) -> None:
    rig = feet_rig(rigs, Wrench((5000.0, -5000.0, 0), (400.0, 0, 0)), Wrench((0, 0, 0), (0, 0, 0)))
    wrench = rig.tick().wrenches[0]
    assert np.allclose(wrench.force_n[:2], [3276.7, -3276.8]) and wrench.torque_nm[0] == 327.67


def test_tare_offsets(rigs: list[Rig]) -> None:
    nodes = [
        LinkEncoderNode(1, lambda: 0.0),
        ForceTorqueSensorNode(21, Wrench((1, 2, 3), (4, 5, 6))),
    ]
    config = ForceTorqueSensorConfig(
        21, force_offset_n=(1.0, 2.0, 3.0), torque_offset_nm=(4.0, 5.0, 6.0)
    )
    rig = Rig(nodes, [LinkEncoderConfig(1)], [config])
    rigs.append(rig)
    rig.open()
    wrench = rig.tick().wrenches[0]
    assert np.allclose(wrench.force_n, 0.0) and np.allclose(wrench.torque_nm, 0.0)


def test_missing_or_half_answers_are_invalid(rigs: list[Rig]) -> None:
    rig = feet_rig(rigs, Wrench((0, 0, 100), (0, 0, 0)), Wrench((0, 0, 200), (0, 0, 0)))
    assert rig.tick().all_valid
    reading = rig.tick(pump=False)  # nobody answers this SYNC
    assert not reading.all_valid
    assert all(not w.valid and np.all(np.isnan(w.force_n)) for w in reading.wrenches)
    assert reading.wrenches[0].age_s == pytest.approx(TICK_S)
    # only the force TPDO of the left foot arrives: half a wrench is not a reading
    rig.now_s += TICK_S
    rig.reader.send_sync()
    rig.runner.pump(rig.now_s)
    frames = []
    while (msg := rig.reader._bus.recv(timeout=0.01)) is not None:
        frames.append(msg)
    for msg in frames:
        if msg.arbitration_id != 0x280 + 21:  # drop the left foot's moments
            rig.node_bus.send(msg)  # the reader's bus sees what the node bus sends
    reading = rig.reader.collect(0.002)
    assert not reading.wrenches[0].valid and reading.wrenches[1].valid


def test_stale_and_dead_sensor(rigs: list[Rig]) -> None:
    left = Wrench((0, 0, 100), (1, 0, 0))
    nodes_rig = feet_rig(rigs, left, Wrench((0, 0, 200), (0, 0, 0)))
    node = nodes_rig.runner.segment.nodes[2]
    assert isinstance(node, ForceTorqueSensorNode)
    nodes_rig.tick()
    node.fault.mode = "stale"
    left.force[2] = 300.0
    left.torque[0] = -1.0
    wrench = nodes_rig.tick().wrenches[0]
    assert wrench.valid and wrench.force_n[2] == 100.0 and wrench.torque_nm[0] == 1.0
    node.fault.mode = "dead"
    wrench = nodes_rig.tick().wrenches[0]
    assert not wrench.valid


def test_open_refuses_a_node_that_is_not_a_six_axis_sensor(rigs: list[Rig]) -> None:
    nodes = [LinkEncoderNode(1, lambda: 0.0), LinkEncoderNode(21, lambda: 0.0)]
    rig = Rig(nodes, [LinkEncoderConfig(1)], [ForceTorqueSensorConfig(21)])
    rigs.append(rig)
    with pytest.raises(CanDeviceError, match="not a CiA 404"):
        rig.open()


def test_configuration_is_validated() -> None:
    with pytest.raises(ValueError, match="two different TPDOs"):
        ForceTorqueSensorConfig(21, force_tpdo=2, torque_tpdo=2)
    with pytest.raises(ValueError, match="three finite"):
        ForceTorqueSensorConfig(21, force_offset_n=(0.0, math.nan, 0.0))


def test_zmp_of_the_standing_robot_through_the_bus(rigs: list[Rig]) -> None:
    """End to end: the emulated robot's feet -> CiA 404 nodes -> CAN -> the driver -> the ZMP
    (controller) equals the CoM's ground projection of the robot standing still."""
    from pathlib import Path

    from controller.humanoid import (
        WALKING_READY_LEG_ANGLES_RAD,
        FootWrench,
        LegModel,
        zmp_from_foot_wrenches,
    )
    from sim_backend.dynamixel.device import H54Device
    from sim_backend.humanoid.robot import EmulatedRobot

    urdf = (Path(__file__).resolve().parents[2] / "hil/data/robots/dyros_jet.urdf").read_text()
    devices = [H54Device(i + 1) for i in range(12)]
    robot = EmulatedRobot(urdf, devices, initial_leg_angles_rad=WALKING_READY_LEG_ANGLES_RAD)
    for device in devices:
        device.set_item("Torque Enable", 1)
    robot.advance(1.5)
    nodes = [
        LinkEncoderNode(1, lambda: robot.link_angle_rad(0)),
        ForceTorqueSensorNode(21, lambda: robot.foot_wrench(0)),
        ForceTorqueSensorNode(22, lambda: robot.foot_wrench(1)),
    ]
    rig = Rig(
        nodes,
        [LinkEncoderConfig(1)],
        [ForceTorqueSensorConfig(21, "left foot"), ForceTorqueSensorConfig(22, "right foot")],
    )
    rigs.append(rig)
    rig.open()
    reading = rig.tick()
    feet = []
    for side, wrench in enumerate(reading.wrenches):
        position, rotation = robot.plant.ft_sensor_pose(side)
        feet.append(FootWrench(wrench.force_n, wrench.torque_nm, position, rotation))
    zmp = zmp_from_foot_wrenches(feet)
    assert np.allclose(zmp, robot.plant.centre_of_mass_m[:2], atol=2e-3)
    # as the host computes it: sensor poses from the link angles, the left sole flat at the origin
    model = LegModel(urdf)
    q = model.standing_configuration(robot.plant.link_angle_rad, side=0)
    model.update_kinematics(q)
    host_feet = [
        FootWrench(
            wrench.force_n,
            wrench.torque_nm,
            model.ft_sensor_placement(side).translation,
            model.ft_sensor_placement(side).rotation,
        )
        for side, wrench in enumerate(reading.wrenches)
    ]
    position, rotation = robot.plant.ft_sensor_pose(0)
    left_sole = position + rotation @ [0.01, 0.0, -0.105]  # the sole's centre (the URDF's box)
    host_zmp = zmp_from_foot_wrenches(host_feet) + left_sole[:2]
    assert np.allclose(host_zmp, zmp, atol=2e-3)
    total = sum(w.force_n[2] for w in reading.wrenches)
    assert total == pytest.approx(49.95809 * 9.81, rel=3e-3)
