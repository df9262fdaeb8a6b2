"""The emulated fixed-base robot as the buses see them (`EmulatedHardware`): a DYNAMIXEL PRO
device of each joint's model, a link encoder per joint that has one, the block's CiA 404 force
sensor, on one MuJoCo robot from its URDF (`FixedBasePlant`) behind the joints' firmwares
(`FlexibleJointRobot`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from sim_backend.canbus import ForceSensorNode, LinkEncoderNode
from sim_backend.canbus.ft_sensor_node import ForceTorqueSensorNode
from sim_backend.dynamixel import DynamixelProDevice
from sim_backend.fixed_base.params import FixedBaseTruthParams
from sim_backend.fixed_base.plant import FixedBasePlant
from sim_backend.flexible_robot import FlexibleJointRobot
from sim_backend.hardware import (
    EncoderSources,
    PlantClock,
    SampleInstant,
    baud_index,
    link_encoders,
    rng,
)
from sim_backend.servo_bank import H54FirmwareBank
from sim_backend.servo_models import servo_params_for
from sim_backend.spec import EmulatorSpec, ToolPushSpec
from sim_backend.testbed import Mounting


class ToolPush:
    """A push of the scenario at the tool point (`ToolPushSpec`), as the robot's loop asks."""

    def __init__(self, spec: ToolPushSpec) -> None:
        self.spec = spec
        self._force = np.asarray(spec.force_n, dtype=float)

    def force_at(self, time_s: float) -> np.ndarray:
        active = self.spec.start_s <= time_s < self.spec.start_s + self.spec.duration_s
        return self._force if active else np.zeros(3)


class EmulatedFixedBase(PlantClock):
    """See the module docstring; built from an `EmulatorSpec` whose robot is FIXED_BASE."""

    held_until_started = False  # bolted down: the plant follows the wall clock from power-on
    truth_columns: tuple[str, ...] = ()  # fixed base: every state is on its buses

    def truth_row(self) -> Sequence[float]:
        return ()

    def __init__(
        self,
        robot: FlexibleJointRobot,
        plant: FixedBasePlant,
        devices: list[DynamixelProDevice],
        encoders: list[LinkEncoderNode],
        force_sensor: ForceSensorNode | None,
        sample_instant: SampleInstant,
    ) -> None:
        self.robot = robot
        self.plant = plant
        self.plant_clock = robot
        self.sample_instant = sample_instant
        self.devices = devices
        self.mountings = [
            Mounting(int(d), float(o))
            for d, o in zip(robot.bank.direction, robot.bank.offset_rad, strict=True)
        ]
        self.encoders = encoders
        self.force_sensor = force_sensor
        self.ft_sensors: list[ForceTorqueSensorNode] = []

    @classmethod
    def build(cls, spec: EmulatorSpec) -> EmulatedFixedBase:
        arm = spec.fixed_base
        if arm is None:
            raise ValueError("a fixed-base emulator needs its FixedBaseSpec")
        devices = [
            DynamixelProDevice(
                joint.dxl_id,
                model=joint.model,
                baud_index=baud_index(spec.joint_baudrate(joint), joint.model),
                reboot_time_s=spec.reboot_time_s,
            )
            for joint in spec.joints
        ]
        servos = [servo_params_for(joint.model, spec.servo) for joint in spec.joints]
        truth = FixedBaseTruthParams(**dict(arm.truth))
        gears = truth.gears([joint.model for joint in spec.joints])
        bank = H54FirmwareBank(
            devices,
            servos,
            directions=[joint.motor_direction for joint in spec.joints],
            offsets_rad=[joint.motor_offset_rad for joint in spec.joints],
            rng=rng(spec.seed, 1000),
        )
        plant = FixedBasePlant(
            arm.urdf_text,
            arm.joint_names,
            gears,
            bank.velocity_gains(),
            truth,
            locked_angles_rad=arm.locked_angles_rad,
            tool=(arm.tool_link, arm.tool_point_m, arm.tool_radius_m) if arm.tool_link else None,
            block=arm.block,
        )
        plant.place_at(arm.initial_angles_rad)
        registers = [servo.default_position_gain_register for servo in servos]
        robot = FlexibleJointRobot(bank, plant, registers, plant.set_tool_force)
        robot.pushes = [ToolPush(push) for push in arm.tool_pushes]
        instant = SampleInstant()
        sources = EncoderSources(
            spec,
            lambda: (plant.link_angle_rad.tolist(), plant.link_velocity_rad_s.tolist()),
            lambda: robot.clock.steps,
            instant,
        )
        force_sensor = None
        if spec.force_sensor_node_id:
            force_sensor = ForceSensorNode(
                spec.force_sensor_node_id,
                plant.contact_force_n,
                heartbeat_ms=spec.heartbeat_ms,
                seed=spec.seed * 7919 + 999,
                noise_n_rms=spec.sensor_noise.force_sensor_n_rms,
                bootup_delay_s=spec.can_bootup_delay_s,
            )
        return cls(robot, plant, devices, link_encoders(spec, sources), force_sensor, instant)
