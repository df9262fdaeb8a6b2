"""The emulated DYROS-JET legs as the buses see them (`EmulatedHardware`): 12 H54 devices, a
link encoder per joint and a six-axis force/torque sensor per foot, on the MuJoCo robot."""

from __future__ import annotations

from sim_backend.canbus import ForceSensorNode, LinkEncoderNode
from sim_backend.canbus.ft_sensor_node import ForceTorqueSensorNode
from sim_backend.dynamixel import H54Device
from sim_backend.hardware import (
    EncoderSources,
    PlantClock,
    SampleInstant,
    baud_index,
    check_joint_count,
    link_encoders,
    rng,
)
from sim_backend.humanoid.params import N_LEG_JOINTS, RobotTruthParams, leg_eeprom_overrides
from sim_backend.humanoid.robot import EmulatedRobot, PelvisPush
from sim_backend.spec import EmulatorSpec
from sim_backend.testbed import Mounting


class EmulatedHumanoid(PlantClock):
    """See the module docstring; built from an `EmulatorSpec` whose robot is HUMANOID."""

    held_until_started = True  # in its gantry until the run starts (realtime clock)
    # the pelvis (base_link) in the world: position [m] and orientation (x, y, z, w)
    truth_columns = (
        "base_x_m", "base_y_m", "base_z_m", "base_qx", "base_qy", "base_qz", "base_qw",
    )  # fmt: skip

    def truth_row(self) -> list[float]:
        plant = self.robot.plant
        w, x, y, z = plant.pelvis_quaternion_wxyz
        return [*plant.pelvis_position_m.tolist(), x, y, z, w]

    def __init__(
        self,
        robot: EmulatedRobot,
        devices: list[H54Device],
        encoders: list[LinkEncoderNode],
        ft_sensors: list[ForceTorqueSensorNode],
        sample_instant: SampleInstant,
    ) -> None:
        self.robot = robot
        self.plant_clock = robot
        self.sample_instant = sample_instant
        self.devices = devices
        self.mountings = list(robot.mountings)
        self.encoders = encoders
        self.force_sensor: ForceSensorNode | None = None
        self.ft_sensors = ft_sensors

    @classmethod
    def build(cls, spec: EmulatorSpec) -> EmulatedHumanoid:
        humanoid = spec.humanoid
        if humanoid is None:
            raise ValueError("a humanoid emulator needs its HumanoidSpec")
        check_joint_count("DYROS-JET's legs", spec.joints, N_LEG_JOINTS)
        devices = [
            H54Device(
                joint.dxl_id,
                baud_index=baud_index(spec.joint_baudrate(joint)),
                reboot_time_s=spec.reboot_time_s,
                eeprom_overrides=leg_eeprom_overrides(),
            )
            for joint in spec.joints
        ]
        truth = RobotTruthParams(**{"servo": spec.servo, **dict(humanoid.truth)})
        robot = EmulatedRobot(
            humanoid.urdf_text,
            devices,
            truth=truth,
            initial_leg_angles_rad=humanoid.initial_leg_angles_rad,
            support_feet=humanoid.support_feet,
            motor_mountings=[
                Mounting(joint.motor_direction, joint.motor_offset_rad) for joint in spec.joints
            ],
            rng=rng(spec.seed, 1000),
            floor_boxes=humanoid.floor_boxes,
            suspended=humanoid.suspended,
        )
        robot.pushes = [
            PelvisPush(p.start_s, p.duration_s, tuple(p.force_n))
            for p in spec.scenario.pelvis_pushes
        ]
        instant = SampleInstant()
        plant = robot.plant
        sources = EncoderSources(
            spec,
            lambda: (plant.link_angle_rad.tolist(), plant.link_velocity_rad_s.tolist()),
            lambda: robot.clock.steps,
            instant,
        )
        encoders = link_encoders(spec, sources)
        ft_sensors = [
            ForceTorqueSensorNode(
                node_id,
                lambda side=side: robot.foot_wrench(side),
                heartbeat_ms=spec.heartbeat_ms,
                seed=spec.seed * 7919 + 500 + side,
                bootup_delay_s=spec.can_bootup_delay_s,
            )
            for side, node_id in enumerate(humanoid.ft_sensor_node_ids)
            if node_id
        ]
        return cls(robot, devices, encoders, ft_sensors, instant)
