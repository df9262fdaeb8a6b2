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

import contextlib
import dataclasses
import json
import math
import select
import signal
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, TextIO

import can
import numpy as np

from sim_backend.canbus import CanSegment, ForceSensorNode, LinkEncoderNode, SlcanPty
from sim_backend.canbus.slave import DEFAULT_BOOTUP_DELAY_S
from sim_backend.dynamixel import (
    BAUD_RATE_BPS,
    DynamixelChain,
    DynamixelLine,
    H54Device,
)
from sim_backend.plant import ObstacleParams, TestbedPlantParams
from sim_backend.scenario import ONE_SHOT_FAULTS, FaultEvent, Scenario
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
    can_bootup_delay_s: float = DEFAULT_BOOTUP_DELAY_S  # a CAN node's restart after NMT reset

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


class Emulator:
    """The virtual testbed on its buses. `run()` serves until `stop()` or a signal."""

    def __init__(self, spec: EmulatorSpec) -> None:
        self.spec = spec
        self.realtime = spec.clock == "realtime"
        plant_params = _with_obstacle(spec.plant, spec.scenario.obstacle_contact_angle_rad)
        self.devices: list[H54Device] = []
        self.joints: list[EmulatedJoint] = []
        nodes: list[Any] = []
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
            self.devices.append(device)
            self.joints.append(joint)
            nodes.append(
                LinkEncoderNode(
                    joint_spec.encoder_node_id,
                    _link_angle_source(
                        joint, joint_spec.encoder_direction, joint_spec.encoder_offset_rad
                    ),
                    counts_per_rev=joint_spec.encoder_counts_per_rev,
                    direction=joint_spec.encoder_direction,
                    heartbeat_ms=spec.heartbeat_ms,
                    seed=spec.seed * 7919 + index,
                    bootup_delay_s=spec.can_bootup_delay_s,
                )
            )
        self.encoders: list[LinkEncoderNode] = list(nodes)
        self.force_sensor: ForceSensorNode | None = None
        if spec.force_sensor_node_id:
            self.force_sensor = ForceSensorNode(
                spec.force_sensor_node_id,
                lambda: sum(j.plant.contact_force_n() for j in self.joints),
                heartbeat_ms=spec.heartbeat_ms,
                seed=spec.seed * 7919 + 999,
                bootup_delay_s=spec.can_bootup_delay_s,
            )
            nodes.append(self.force_sensor)
        self.testbed = VirtualTestbed(self.joints)
        self.chain = DynamixelChain(self.devices, enforce_baud=True)
        self.line = DynamixelLine(self.chain, realtime=self.realtime)
        self.segment = CanSegment(nodes, bitrate=spec.can_bitrate)
        self.slcan = SlcanPty(bus_bitrate=spec.can_bitrate)
        # The nodes were powered before any host connected: their power-on boot-ups go out now,
        # to the closed channel (later, one could pass for the answer to a host's first reset).
        for frame in self.segment.poll(self._node_time()):
            self.slcan.send_frame(frame)
        self.sync_count = 0
        self._fired: set[int] = set()
        self._started: set[int] = set()  # scenario fault events that were active at least once
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
                # python-can's slcan reads its serial port with this timeout: every empty read
                # blocks this long, and 0 makes every waiting client (canopen's Notifier, any
                # recv loop) spin a core (measured: an idle canopen client used 49-59 % of a
                # core with 0, 4.6 % with 0.001, 1.5 % with 0.01, where an empty poll costs
                # 0.02, 1.1 and 9 ms). 0.001 is python-can's own default. Our driver does not
                # depend on it: it waits in select() on the port (drivers/canbus).
                "timeout": 0.001,
            },
            "encoder_node_ids": [j.encoder_node_id for j in self.spec.joints],
            "force_sensor_node_id": self.spec.force_sensor_node_id or None,
            "clock": self.spec.clock,
            "period_s": self.spec.period_s,
            "seed": self.spec.seed,
        }

    def fault_counts(self) -> dict[str, Any]:
        """How often each injected fault acted: a run can show that every fault it injected
        really happened. Scenario fault events are numbered as in `spec.scenario.faults`."""
        return {
            "scenario_faults_started": sorted(self._started),
            "dynamixel": dataclasses.asdict(self.chain.faults.fired),
            "encoders": {
                str(node.node_id): dataclasses.asdict(node.fault_counts) for node in self.encoders
            },
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
            can_due = self.segment.next_due_s()  # boot-up, heartbeat: on the nodes' clock
            if can_due is not None:
                timeout = min(timeout, max(0.0, can_due - self._node_time()))
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
        now = self.testbed.scenario_time_s
        faults = self.chain.faults
        silent: set[int] = set()
        dropped: set[int] = set()
        corrupted: set[int] = set()
        encoder_modes = ["ok"] * len(self.encoders)
        encoder_noise = [0.0] * len(self.encoders)
        for number, event in enumerate(self.spec.scenario.faults):
            if now is None or not event.start_s <= now < event.end_s:
                continue
            self._started.add(number)
            dxl_id = self.spec.joints[event.joint].dxl_id
            if event.kind in ONE_SHOT_FAULTS and event.duration_s is None:
                if number not in self._fired:
                    self._fired.add(number)
                    if event.kind == "dropped_reply":
                        faults.drop_next_replies += 1
                    else:
                        faults.corrupt_next_replies += 1
                continue
            _activate(event, dxl_id, silent, dropped, corrupted, encoder_modes, encoder_noise)
        faults.silent_ids.clear()
        faults.silent_ids.update(silent)
        faults.drop_reply_ids.clear()
        faults.drop_reply_ids.update(dropped)
        faults.corrupt_crc_ids.clear()
        faults.corrupt_crc_ids.update(corrupted)
        for node, mode, noise in zip(self.encoders, encoder_modes, encoder_noise, strict=True):
            if node.fault.mode != mode or node.fault.noise_counts_rms != noise:
                node.fault.mode = mode
                node.fault.noise_counts_rms = noise

    def close(self) -> None:
        self.line.close()
        self.slcan.close()


def _activate(
    event: FaultEvent,
    dxl_id: int,
    silent: set[int],
    dropped: set[int],
    corrupted: set[int],
    encoder_modes: list[str],
    encoder_noise: list[float],
) -> None:
    if event.kind == "silent_id":
        silent.add(dxl_id)
    elif event.kind == "dropped_reply":
        dropped.add(dxl_id)
    elif event.kind == "corrupt_crc":
        corrupted.add(dxl_id)
    elif event.kind == "dead_encoder":
        encoder_modes[event.joint] = "dead"
    elif event.kind == "stale_encoder":
        encoder_modes[event.joint] = "stale"
    elif event.kind == "noisy_encoder":
        encoder_modes[event.joint] = "noisy"
        encoder_noise[event.joint] = event.noise_counts_rms


def _link_angle_source(joint: EmulatedJoint, direction: int, offset_rad: float):  # noqa: ANN202
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
    """Build the emulator, print its endpoints as one JSON line, serve until SIGINT/SIGTERM,
    then print one more JSON line, {"fault_counts": Emulator.fault_counts()}."""
    emulator = Emulator(spec)
    previous = {sig: signal.signal(sig, emulator.stop) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        out.write(json.dumps({**emulator.endpoints(), **(extra or {})}) + "\n")
        out.flush()
        emulator.run()
        with contextlib.suppress(OSError, ValueError):  # nobody reads any more: fine
            out.write(json.dumps({"fault_counts": emulator.fault_counts()}) + "\n")
            out.flush()
    finally:
        emulator.close()
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def joint_specs_from_ids(
    ids: Sequence[int], first_node_id: int = 5
) -> tuple[EmulatedJointSpec, ...]:
    """Joints with consecutive encoder node IDs (for benches that only care about the chain)."""
    return tuple(
        EmulatedJointSpec(dxl_id=i, encoder_node_id=first_node_id + n) for n, i in enumerate(ids)
    )
