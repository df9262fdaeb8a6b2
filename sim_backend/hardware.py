"""The emulated hardware of a spec, before any bus is attached: devices, sensors, physics.

Two robots, one face (`EmulatedHardware`), which the bus server (sim_backend/server.py) and the
in-process testbed (sim_backend/direct.py) both drive:

    testbed    one MuJoCo plant per joint behind its H54 firmware (sim_backend/testbed.py),
               a CiA 406 link encoder per joint, the obstacle's CiA 404 force sensor
    dyros-jet  the humanoid's 12 leg joints on one MuJoCo robot behind 12 H54 firmwares
               (sim_backend/humanoid/), a link encoder per joint, a six-axis force/torque
               sensor per foot

Every device is a `DynamixelProDevice` of its joint's model (the testbed's joints may be any
model of the family: `EmulatedJointSpec.model`, its servo figures from
`sim_backend.servo_models`), and every sensor is a CAN node
(`CanopenSlave`), so the buses and the drivers see the same thing whichever robot it is.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from functools import partial
from typing import Protocol

import numpy as np

from sim_backend.canbus import ForceSensorNode, LinkEncoderNode
from sim_backend.canbus.ft_sensor_node import ForceTorqueSensorNode
from sim_backend.dynamixel import BAUD_RATE_BPS, DynamixelProDevice, device_model
from sim_backend.plant import ObstacleParams, TestbedPlantParams
from sim_backend.servo_models import servo_params_for
from sim_backend.spec import EmulatorSpec
from sim_backend.testbed import EmulatedJoint, Mounting, VirtualTestbed


@dataclasses.dataclass
class SampleInstant:
    """How long after the plant's last physics step the sensors sample [s].

    The plant advances in whole steps (1 ms) and a SYNC arrives between them: the realtime
    emulator sets this when a SYNC arrives, and the link encoders latch the angle at that
    instant (the last step's angle plus velocity times this), as a real encoder latches on the
    SYNC, not on the emulator's last step. Without it the latched instant would jitter by up
    to a step: at 0.8 rad/s (the link during an impact) that is 1e-3 rad of second difference
    from tick to tick, which the supervisor rightly calls a noisy sensor. 0 in lock-step, where
    the SYNC and the step coincide."""

    after_step_s: float = 0.0


class SteppedPlant(Protocol):
    """What steps the physics: the clock members of `EmulatedHardware` (and of its plants)."""

    @property
    def physics_timestep_s(self) -> float: ...

    @property
    def time_s(self) -> float: ...

    @property
    def scenario_time_s(self) -> float | None: ...

    def start_scenario(self) -> None: ...

    def advance(self, duration_s: float) -> int: ...


class EmulatedHardware(SteppedPlant, Protocol):
    """What the buses serve and the physics clock they share (see the module docstring)."""

    devices: list[DynamixelProDevice]  # one per joint, in the spec's joint order
    mountings: list[Mounting]  # how each actuator is mounted (the host's offset/direction)
    encoders: list[LinkEncoderNode]  # one per joint
    force_sensor: ForceSensorNode | None
    ft_sensors: list[ForceTorqueSensorNode]
    sample_instant: SampleInstant  # when, past the last step, the sensors latch

    # True: the robot hangs in its gantry (the plant does not move) until the host starts the
    # run (its first SYNC), as a humanoid is held until its joints hold it; False: the plant
    # follows the wall clock from power-on (the testbed's link hangs on its spring meanwhile).
    held_until_started: bool

    # What no sensor reports, for the emulator's truth log (sim_backend/truth_log.py): the
    # names of `truth_row()`'s values (none: nothing to log)
    truth_columns: tuple[str, ...]

    def truth_row(self) -> Sequence[float]: ...


def sensor_nodes(hardware: EmulatedHardware) -> list[object]:
    """Every CAN node of the hardware (encoders, force sensor, force/torque sensors)."""
    nodes: list[object] = list(hardware.encoders)
    if hardware.force_sensor is not None:
        nodes.append(hardware.force_sensor)
    nodes.extend(hardware.ft_sensors)
    return nodes


def baud_index(baudrate: int, model: str | None = None) -> int:
    """The Baud Rate item value of `baudrate` on `model` (None: the PRO's table)."""
    if model is not None:
        return device_model(model).baud_index(baudrate)
    return next(index for index, bps in BAUD_RATE_BPS.items() if bps == baudrate)


def rng(seed: int, stream: int) -> np.random.Generator:
    return np.random.default_rng([seed, stream])


class EncoderSources:
    """What the link encoders latch, for all joints at once: joint i's link angle `instant`
    past the last physics step plus its encoder's offset term, link_angle + link_velocity x
    after_step_s + direction x offset, computed once per physics step and instant (every
    encoder reads it at every SYNC).

    link_state() gives every joint's (link angles, link velocities) as lists; steps() counts
    the physics steps (the plant moves only by a step)."""

    def __init__(
        self,
        spec: EmulatorSpec,
        link_state: Callable[[], tuple[list[float], list[float]]],
        steps: Callable[[], int],
        instant: SampleInstant,
    ) -> None:
        self._link_state = link_state
        self._steps = steps
        self._instant = instant
        # The node multiplies by its direction; the driver computes direction * (reading -
        # offset): the source is the encoder's own angle, before the node's direction.
        self._offset_terms = [
            joint.encoder_direction * joint.encoder_offset_rad for joint in spec.joints
        ]
        self._key: tuple[int, float] | None = None
        self._values: list[float] = []

    def value(self, index: int) -> float:
        key = (self._steps(), self._instant.after_step_s)
        if key != self._key:  # (Python floats: as cheap as numpy for 12, cheaper for one)
            angles, velocities = self._link_state()
            after = key[1]
            self._values = [
                angle + velocity * after + offset
                for angle, velocity, offset in zip(
                    angles, velocities, self._offset_terms, strict=True
                )
            ]
            self._key = key
        return self._values[index]


def link_encoders(spec: EmulatorSpec, sources: EncoderSources) -> list[LinkEncoderNode]:
    """A CiA 406 link encoder per joint that has one (`encoder_node_id` 0: none, a stock
    arm), latching `sources.value(joint)` (its link angle at the SYNC's instant, see
    `SampleInstant`), mounted as the spec says."""
    nodes = []
    for index, joint in enumerate(spec.joints):
        if not joint.encoder_node_id:
            continue
        nodes.append(
            LinkEncoderNode(
                joint.encoder_node_id,
                partial(sources.value, index),
                counts_per_rev=joint.encoder_counts_per_rev,
                direction=joint.encoder_direction,
                heartbeat_ms=spec.heartbeat_ms,
                seed=spec.seed * 7919 + index,
                noise_counts_rms=spec.sensor_noise.link_encoder_counts_rms,
                bootup_delay_s=spec.can_bootup_delay_s,
            )
        )
    return nodes


def with_obstacle(
    params: TestbedPlantParams, contact_angle_rad: float | None
) -> TestbedPlantParams:
    """The block is part of an experiment's world: present only where the scenario puts it."""
    if contact_angle_rad is None:
        return dataclasses.replace(params, obstacle=None)
    approach = 1 if contact_angle_rad > params.initial_link_angle_rad else -1
    obstacle = ObstacleParams(contact_angle_rad=contact_angle_rad, approach=approach)
    return dataclasses.replace(params, obstacle=obstacle)


class PlantClock:
    """`EmulatedHardware`'s clock members, passed on to `self.plant_clock`."""

    plant_clock: SteppedPlant

    @property
    def physics_timestep_s(self) -> float:
        return self.plant_clock.physics_timestep_s

    @property
    def time_s(self) -> float:
        return self.plant_clock.time_s

    @property
    def scenario_time_s(self) -> float | None:
        return self.plant_clock.scenario_time_s

    def start_scenario(self) -> None:
        self.plant_clock.start_scenario()

    def advance(self, duration_s: float) -> int:
        return self.plant_clock.advance(duration_s)


class EmulatedTestbed(PlantClock):
    """The 1-DoF testbed (or n copies of it): a plant per joint behind its H54 firmware."""

    held_until_started = False
    truth_columns: tuple[str, ...] = ()  # every state of the testbed is on its buses

    def truth_row(self) -> Sequence[float]:
        return ()

    def __init__(
        self,
        devices: list[DynamixelProDevice],
        joints: list[EmulatedJoint],
        encoders: list[LinkEncoderNode],
        force_sensor: ForceSensorNode | None,
        sample_instant: SampleInstant,
    ) -> None:
        self.devices = devices
        self.joints = joints
        self.sample_instant = sample_instant
        self.mountings = [joint.motor_mounting for joint in joints]
        self.encoders = encoders
        self.force_sensor = force_sensor
        self.ft_sensors: list[ForceTorqueSensorNode] = []
        self.testbed = VirtualTestbed(joints)
        self.plant_clock = self.testbed

    @classmethod
    def build(cls, spec: EmulatorSpec) -> EmulatedTestbed:
        plant_params = with_obstacle(spec.plant, spec.scenario.obstacle_contact_angle_rad)
        devices: list[DynamixelProDevice] = []
        joints: list[EmulatedJoint] = []
        for index, joint_spec in enumerate(spec.joints):
            device = DynamixelProDevice(
                joint_spec.dxl_id,
                model=joint_spec.model,
                baud_index=baud_index(spec.joint_baudrate(joint_spec), joint_spec.model),
                reboot_time_s=spec.reboot_time_s,
            )
            joint = EmulatedJoint(
                device,
                plant_params,
                servo_params_for(joint_spec.model, spec.servo),
                motor_mounting=Mounting(joint_spec.motor_direction, joint_spec.motor_offset_rad),
                rng=rng(spec.seed, 1000 + index),
            )
            joint.pushes = [p for p in spec.scenario.pushes if p.joint == index]
            device.add_reboot_listener(joint.on_reboot)
            devices.append(device)
            joints.append(joint)
        instant = SampleInstant()
        hardware = cls(devices, joints, [], None, instant)
        sources = EncoderSources(
            spec,
            lambda: (
                [joint.plant.link_angle_rad for joint in joints],
                [joint.plant.link_velocity_rad_s for joint in joints],
            ),
            lambda: hardware.testbed.clock.steps,
            instant,
        )
        hardware.encoders = link_encoders(spec, sources)
        if spec.force_sensor_node_id:
            hardware.force_sensor = ForceSensorNode(
                spec.force_sensor_node_id,
                hardware.contact_force_n,
                heartbeat_ms=spec.heartbeat_ms,
                seed=spec.seed * 7919 + 999,
                noise_n_rms=spec.sensor_noise.force_sensor_n_rms,
                bootup_delay_s=spec.can_bootup_delay_s,
            )
        return hardware

    def contact_force_n(self) -> float:
        return sum(j.plant.contact_force_n() for j in self.joints)


def check_joint_count(name: str, joints: Sequence[object], expected: int) -> None:
    if len(joints) != expected:
        raise ValueError(f"the {name} has {expected} joints; the spec gives {len(joints)}")
