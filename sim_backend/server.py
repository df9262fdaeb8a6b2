"""The emulator process: the virtual testbed served on its two buses until interrupted.

One single-threaded event loop owns everything, so nothing depends on thread scheduling:

    the Dynamixel chain    a pty speaking Protocol 2.0 (`DynamixelLine`)
    the CAN segment        link-encoder nodes (+ the force sensor) behind an emulated serial-line
                           CAN adapter on a second pty (`SlcanPty`; python-can's `slcan`)
    the physics            one MuJoCo plant per joint behind its H54 firmware (`VirtualTestbed`)

Clocks:
- lockstep: the plant advances exactly one loop period per CAN SYNC it receives (the first SYNC
  samples t = 0). Before stepping, the loop drains the Dynamixel line, so the goals the host
  wrote before that SYNC act over the period that follows it: a run is deterministic whatever the
  machine's load. The host must read the Dynamixel state only after the SYNC's TPDOs arrived
  (our driver does).
- realtime: the plant follows the wall clock (1 ms physics steps), the Dynamixel line models wire
  time and Return Delay Time, nothing waits for SYNC: the emulated testbed behaves like the
  hardware, for ROBOTIS's SDK or any other client.

The first line on stdout is one JSON object telling a host how to reach the buses.
"""

from __future__ import annotations

import dataclasses
import json
import math
import select
import signal
import sys
import time
from dataclasses import dataclass, field
from typing import Any, TextIO

import can
import numpy as np

from sim_backend.canbus import CanSegment, ForceSensorNode, LinkEncoderNode, SlcanPty
from sim_backend.canbus.encoder_node import RLC2IC_NOISE_COUNTS_RMS
from sim_backend.canbus.force_sensor_node import FORCE_SENSOR_NOISE_N_RMS
from sim_backend.dynamixel import (
    BAUD_RATE_BPS,
    DynamixelChain,
    DynamixelLine,
    H54Device,
)
from sim_backend.plant import ObstacleParams, TestbedPlantParams
from sim_backend.scenario import FaultSchedule, Scenario
from sim_backend.servo import H54ServoParams
from sim_backend.testbed import EmulatedJoint, Mounting, VirtualTestbed

SYNC_COB_ID = 0x080
CLOCKS = ("lockstep", "realtime")


@dataclass(frozen=True)
class EmulatedJointSpec:
    """One emulated joint: its bus addresses and how its sensors are mounted."""

    dxl_id: int
    encoder_node_id: int
    encoder_counts_per_rev: int = 983_040
    encoder_direction: int = 1
    encoder_offset_rad: float = 0.0
    motor_direction: int = 1
    motor_offset_rad: float = 0.0


@dataclass(frozen=True)
class SensorNoise:
    """Measurement noise of the emulated CAN sensors, zero-mean Gaussian before each device's
    rounding, drawn from generators seeded by `EmulatorSpec.seed` (same seed, same values; the
    H54's own Present Current / Velocity noise is in `H54ServoParams`).

    link_encoder_counts_rms: every link encoder's read-head noise [counts rms]; nominal 0.5
        (`sim_backend.canbus.encoder_node`: RLS give no jitter figure; ~1 count of flicker).
    force_sensor_n_rms: the obstacle's force sensor [N rms]; nominal 0.05 N (an assumption: the
        paper names no sensor; `sim_backend.canbus.force_sensor_node`).
    """

    link_encoder_counts_rms: float = RLC2IC_NOISE_COUNTS_RMS
    force_sensor_n_rms: float = FORCE_SENSOR_NOISE_N_RMS

    def __post_init__(self) -> None:
        for name in ("link_encoder_counts_rms", "force_sensor_n_rms"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"sensor noise {name} must be a finite rms >= 0, got {value}")


@dataclass(frozen=True)
class EmulatorSpec:
    """Everything the emulator process needs; `hil` builds it from the configuration file."""

    joints: tuple[EmulatedJointSpec, ...]
    baudrate: int = 3_000_000
    can_bitrate: int = 1_000_000
    force_sensor_node_id: int = 0
    period_s: float = 0.005
    clock: str = "lockstep"
    seed: int = 0
    plant: TestbedPlantParams = field(default_factory=TestbedPlantParams)
    servo: H54ServoParams = field(default_factory=H54ServoParams)
    scenario: Scenario = field(default_factory=Scenario)
    reboot_time_s: float = 0.5
    heartbeat_ms: int = 100
    sensor_noise: SensorNoise = field(default_factory=SensorNoise)

    def __post_init__(self) -> None:
        if not self.joints:
            raise ValueError("the emulator needs at least one joint")
        if self.clock not in CLOCKS:
            raise ValueError(f"clock must be one of {CLOCKS}, got {self.clock!r}")
        if self.baudrate not in BAUD_RATE_BPS.values():
            raise ValueError(
                f"an H54 cannot run at {self.baudrate} bps; its Baud Rate item offers "
                f"{sorted(BAUD_RATE_BPS.values())}"
            )
        if not self.period_s > 0:
            raise ValueError("period_s must be > 0")


def _baud_index(baudrate: int) -> int:
    return next(index for index, bps in BAUD_RATE_BPS.items() if bps == baudrate)


@dataclass
class EmulatedRobot:
    """The emulated devices and physics of a spec, before any bus is attached to them."""

    devices: list[H54Device]
    joints: list[EmulatedJoint]
    testbed: VirtualTestbed
    plant_params: TestbedPlantParams

    @classmethod
    def build(cls, spec: EmulatorSpec) -> EmulatedRobot:
        plant_params = _with_obstacle(spec.plant, spec.scenario.obstacle_contact_angle_rad)
        devices: list[H54Device] = []
        joints: list[EmulatedJoint] = []
        for index, joint_spec in enumerate(spec.joints):
            device = H54Device(
                joint_spec.dxl_id,
                baud_index=_baud_index(spec.baudrate),
                reboot_time_s=spec.reboot_time_s,
            )
            joint = EmulatedJoint(
                device,
                plant_params,
                spec.servo,
                motor_mounting=Mounting(joint_spec.motor_direction, joint_spec.motor_offset_rad),
                rng=_rng(spec.seed, 1000 + index),
            )
            joint.pushes = [p for p in spec.scenario.pushes if p.joint == index]
            device.add_reboot_listener(joint.on_reboot)
            devices.append(device)
            joints.append(joint)
        return cls(devices, joints, VirtualTestbed(joints), plant_params)

    def contact_force_n(self) -> float:
        return sum(j.plant.contact_force_n() for j in self.joints)

    def sensor_nodes(
        self, spec: EmulatorSpec
    ) -> tuple[list[LinkEncoderNode], ForceSensorNode | None]:
        """The CAN sensors on this robot: a link encoder per joint, the obstacle's force sensor."""
        encoders = [
            LinkEncoderNode(
                joint_spec.encoder_node_id,
                _link_angle_source(
                    self.joints[index], joint_spec.encoder_direction, joint_spec.encoder_offset_rad
                ),
                counts_per_rev=joint_spec.encoder_counts_per_rev,
                direction=joint_spec.encoder_direction,
                heartbeat_ms=spec.heartbeat_ms,
                seed=spec.seed * 7919 + index,
                noise_counts_rms=spec.sensor_noise.link_encoder_counts_rms,
            )
            for index, joint_spec in enumerate(spec.joints)
        ]
        force_sensor = None
        if spec.force_sensor_node_id:
            force_sensor = ForceSensorNode(
                spec.force_sensor_node_id,
                self.contact_force_n,
                heartbeat_ms=spec.heartbeat_ms,
                seed=spec.seed * 7919 + 999,
                noise_n_rms=spec.sensor_noise.force_sensor_n_rms,
            )
        return encoders, force_sensor


class Emulator:
    """The virtual testbed on its buses. `run()` serves until `stop()` or a signal."""

    def __init__(self, spec: EmulatorSpec) -> None:
        self.spec = spec
        self.realtime = spec.clock == "realtime"
        robot = EmulatedRobot.build(spec)
        self.robot = robot
        self.devices = robot.devices
        self.joints = robot.joints
        self.encoders, self.force_sensor = robot.sensor_nodes(spec)
        nodes: list[Any] = list(self.encoders)
        if self.force_sensor is not None:
            nodes.append(self.force_sensor)
        self.testbed = robot.testbed
        self.chain = DynamixelChain(self.devices, enforce_baud=True)
        self.line = DynamixelLine(self.chain, realtime=self.realtime)
        self.segment = CanSegment(nodes, bitrate=spec.can_bitrate)
        self.slcan = SlcanPty(bus_bitrate=spec.can_bitrate)
        self.sync_count = 0
        self.fault_schedule = FaultSchedule(spec.scenario.faults, len(spec.joints))
        self._running = False
        self._wall_origin = time.monotonic()

    # --- what a host needs -----------------------------------------------------------------
    def endpoints(self) -> dict[str, Any]:
        return {
            "dynamixel_port": self.line.port_path,
            "baudrate": self.spec.baudrate,
            "ids": [j.dxl_id for j in self.spec.joints],
            "can": {
                "interface": "slcan",
                "channel": self.slcan.port_path,
                "bitrate": self.spec.can_bitrate,
                "sleep_after_open": 0,
                # python-can's slcan polls its serial port with this timeout: 0 makes recv()
                # return at once (it then busy-polls, as dynamixel-sdk does) instead of costing
                # 1 ms per call, half a lock-step tick.
                "timeout": 0,
            },
            "encoder_node_ids": [j.encoder_node_id for j in self.spec.joints],
            "force_sensor_node_id": self.spec.force_sensor_node_id or None,
            "clock": self.spec.clock,
            "period_s": self.spec.period_s,
            "seed": self.spec.seed,
        }

    # --- the event loop --------------------------------------------------------------------
    def stop(self, *_: object) -> None:
        self._running = False

    def run(self) -> None:
        self._running = True
        line, slcan = self.line, self.slcan
        fds = [slcan.fileno(), line.fileno()]
        next_physics = time.monotonic()
        while self._running:
            now = time.monotonic()
            timeout = 0.05
            due = line.next_due_s()
            if due is not None:
                timeout = min(timeout, max(0.0, due - now))
            if self.realtime:
                timeout = min(timeout, max(0.0, next_physics - now))
            try:
                readable, _, _ = select.select(fds, [], [], timeout)
            except InterruptedError:
                continue
            # CAN first: a SYNC must step the plant before a later Dynamixel read is answered.
            if slcan.fileno() in readable:
                for frame in slcan.read_frames():
                    self._on_host_frame(frame)
            if line.fileno() in readable:
                line.on_readable()
            else:
                line.on_idle()
            line.flush_due()
            if self.realtime:
                next_physics = self._follow_wall_clock()
            for frame in self.segment.poll(self._node_time()):
                slcan.send_frame(frame)

    def _on_host_frame(self, frame: can.Message) -> None:
        if frame.arbitration_id == SYNC_COB_ID and not frame.is_remote_frame:
            self._on_sync()
        for reply in self.segment.deliver(frame, self._node_time()):
            self.slcan.send_frame(reply)

    def _on_sync(self) -> None:
        if self.sync_count == 0:
            self.testbed.start_scenario()
        if not self.realtime:
            self.line.drain()  # goals written before this SYNC act over the coming period
            if self.sync_count > 0:
                self.testbed.advance(self.spec.period_s)
        self.sync_count += 1
        self._apply_faults()

    def _follow_wall_clock(self) -> float:
        """Step the plant up to the wall clock; returns when the next step is due."""
        dt = self.testbed.physics_timestep_s
        elapsed = time.monotonic() - self._wall_origin
        behind = elapsed - self.testbed.time_s
        if behind > 0.1:  # we were stopped (debugger, suspended): do not replay the gap
            self._wall_origin += behind - dt
            behind = dt
        if behind >= dt:
            self.testbed.advance(math.floor(behind / dt) * dt)
            self._apply_faults()
        return self._wall_origin + self.testbed.time_s + dt

    def _node_time(self) -> float:
        return time.monotonic()

    # --- faults ----------------------------------------------------------------------------
    def _apply_faults(self) -> None:
        active = self.fault_schedule.at(self.testbed.scenario_time_s)
        faults = self.chain.faults
        ids = [joint.dxl_id for joint in self.spec.joints]
        faults.drop_next_replies += len(active.drop_next)
        faults.corrupt_next_replies += len(active.corrupt_next)
        for target, joints in (
            (faults.silent_ids, active.silent),
            (faults.drop_reply_ids, active.dropped),
            (faults.corrupt_crc_ids, active.corrupted),
        ):
            target.clear()
            target.update(ids[j] for j in joints)
        for node, mode, noise in zip(
            self.encoders, active.encoder_mode, active.encoder_noise_counts_rms, strict=True
        ):
            if node.fault.mode != mode or node.fault.noise_counts_rms != noise:
                node.fault.mode = mode
                node.fault.noise_counts_rms = noise

    def close(self) -> None:
        self.line.close()
        self.slcan.close()


def _link_angle_source(joint: EmulatedJoint, direction: int, offset_rad: float):
    """The encoder's own angle (before the node's direction): undone by the driver's offset."""
    plant = joint.plant
    # The node multiplies by its direction; the driver computes direction * (reading - offset).
    return lambda: plant.link_angle_rad + direction * offset_rad


def _rng(seed: int, stream: int) -> np.random.Generator:
    return np.random.default_rng([seed, stream])


def _with_obstacle(
    params: TestbedPlantParams, contact_angle_rad: float | None
) -> TestbedPlantParams:
    """The block is part of an experiment's world: present only where the scenario puts it."""
    if contact_angle_rad is None:
        return dataclasses.replace(params, obstacle=None)
    approach = 1 if contact_angle_rad > params.initial_link_angle_rad else -1
    obstacle = ObstacleParams(contact_angle_rad=contact_angle_rad, approach=approach)
    return dataclasses.replace(params, obstacle=obstacle)


def serve(spec: EmulatorSpec, out: TextIO = sys.stdout, extra: dict | None = None) -> None:
    """Build the emulator, print its endpoints as one JSON line, serve until SIGINT/SIGTERM."""
    emulator = Emulator(spec)
    previous = {sig: signal.signal(sig, emulator.stop) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        out.write(json.dumps({**emulator.endpoints(), **(extra or {})}) + "\n")
        out.flush()
        emulator.run()
    finally:
        emulator.close()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
