"""How far the emulator is from its physics: per-tick emulator work against MuJoCo alone.

`EmulatorBench(spec)` builds the emulated hardware of a spec with every actuator's torque on
(as a host would leave it) and times, each call on its own so that a benchmark can interleave
them (A B A B ...) on a shared machine:

    mujoco_alone_s(steps)   plain `mujoco.mj_step` on a copy of the plant's model and state
                            (every MuJoCo plant of the hardware: the humanoid's one, the
                            testbed's one per joint), nothing else: the physics limit
    advance_s(ticks)        `EmulatedHardware.advance(period)` per tick: the firmware bank,
                            the plant's inputs and outputs and MuJoCo
    tick_s(ticks)           a lock-step tick's whole emulator work without the ptys: advance,
                            one SYNC_WRITE of the goals, one SYNC_READ of the 611..622 block,
                            the CAN SYNC with every node's TPDOs, encoded as slcan lines
    in_process_s(ticks)     the same tick in process (`DirectTestbed`, what the in-process
                            joint bus drives): sync (advance), read of every sensor in SI, the
                            goals written

Each returns wall seconds (time.perf_counter); divide by steps or ticks. The figures are
machine- and load-dependent: compare them only side by side, in one run.
"""

from __future__ import annotations

import copy
import time
from typing import Any

import can
import mujoco
import numpy as np

from sim_backend.canbus import CanSegment
from sim_backend.canbus.slcan_pty import encode_frame
from sim_backend.direct import DirectTestbed
from sim_backend.dynamixel import DynamixelChain
from sim_backend.dynamixel.protocol import BROADCAST_ID, Instruction, build_instruction_packet
from sim_backend.hardware import EmulatedHardware, sensor_nodes
from sim_backend.robots import build_hardware
from sim_backend.spec import EmulatorSpec

_PRESENT_BLOCK = (611, 12)  # Present Position .. Present Current (the drivers' sync read)
_SYNC = can.Message(arbitration_id=0x080, data=b"", is_extended_id=False)


def mujoco_plants(hardware: EmulatedHardware) -> list[Any]:
    """The MuJoCo plants of the hardware (anything with `model` and `data`)."""
    robot = getattr(hardware, "robot", None)
    if robot is not None:
        return [robot.plant]
    return [joint.plant for joint in getattr(hardware, "joints", [])]


class EmulatorBench:
    """See the module docstring."""

    def __init__(self, spec: EmulatorSpec) -> None:
        self.spec = spec
        self.hardware = build_hardware(spec)
        for device in self.hardware.devices:
            device.write_item("Torque Enable", 1)
        self.hardware.start_scenario()
        self.hardware.advance(spec.period_s)
        self._physics = [
            (plant.model, copy.copy(plant.data)) for plant in mujoco_plants(self.hardware)
        ]
        ids = [device.dxl_id for device in self.hardware.devices]
        address, length = _PRESENT_BLOCK
        self._sync_read = build_instruction_packet(
            BROADCAST_ID,
            Instruction.SYNC_READ,
            bytes((address & 0xFF, address >> 8, length & 0xFF, length >> 8, *ids)),
        )
        goals = b"".join(
            bytes((dxl_id,)) + device.item("Present Position").to_bytes(4, "little", signed=True)
            for dxl_id, device in zip(ids, self.hardware.devices, strict=True)
        )
        self._sync_write = build_instruction_packet(
            BROADCAST_ID, Instruction.SYNC_WRITE, bytes((596 & 0xFF, 596 >> 8, 4, 0)) + goals
        )
        self._chain = DynamixelChain(self.hardware.devices)
        self._segment = CanSegment(sensor_nodes(self.hardware), bitrate=spec.can_bitrate)
        self._can_time_s = 0.0
        self._start_nodes()
        self._direct = DirectTestbed(spec)
        for joint in range(self._direct.n_joints):
            self._direct.set_torque(joint, True)
        self._direct.sync()
        self._goals = self._direct.read().motor_angle_rad

    def _start_nodes(self) -> None:
        """Every CAN node booted and Operational (NMT start to all), as the host leaves them."""
        self._can_time_s += 1.0
        self._segment.poll(self._can_time_s)
        start_all = can.Message(arbitration_id=0x000, data=b"\x01\x00", is_extended_id=False)
        self._segment.deliver(start_all, self._can_time_s)

    def mujoco_alone_s(self, steps: int) -> float:
        physics = self._physics
        step = mujoco.mj_step
        start = time.perf_counter()
        for _ in range(steps):
            for model, data in physics:
                step(model, data)
        return time.perf_counter() - start

    def advance_s(self, ticks: int) -> float:
        advance, period = self.hardware.advance, self.spec.period_s
        start = time.perf_counter()
        for _ in range(ticks):
            advance(period)
        return time.perf_counter() - start

    def tick_s(self, ticks: int) -> float:
        advance, period = self.hardware.advance, self.spec.period_s
        chain, segment = self._chain, self._segment
        sync_write, sync_read = self._sync_write, self._sync_read
        start = time.perf_counter()
        for _ in range(ticks):
            chain.handle(sync_write, 0.0)
            advance(period)
            self._can_time_s += period
            lines = b"".join(encode_frame(f) for f in segment.deliver(_SYNC, self._can_time_s))
            replies = chain.handle(sync_read, 0.0)
            if not lines or len(replies) != len(self.hardware.devices):
                raise RuntimeError("the emulated buses did not answer the bench's tick")
        return time.perf_counter() - start

    def in_process_s(self, ticks: int) -> float:
        direct, goals = self._direct, self._goals
        start = time.perf_counter()
        for _ in range(ticks):
            direct.sync()
            if not direct.read().motor_valid.all():
                raise RuntimeError("the in-process robot did not answer the bench's tick")
            direct.write_goals(goals)
        return time.perf_counter() - start


def interleaved(bench: EmulatorBench, ticks: int, rounds: int) -> dict[str, float]:
    """Per-tick seconds of MuJoCo alone (the tick's physics steps), `advance`, the whole tick
    and the tick in process, measured in turn `rounds` times (medians)."""
    steps_per_tick = round(bench.spec.period_s / bench.hardware.physics_timestep_s)
    samples: dict[str, list[float]] = {
        "mujoco_alone": [],
        "advance": [],
        "tick": [],
        "in_process": [],
    }
    for _ in range(rounds):
        samples["mujoco_alone"].append(bench.mujoco_alone_s(ticks * steps_per_tick) / ticks)
        samples["advance"].append(bench.advance_s(ticks) / ticks)
        samples["tick"].append(bench.tick_s(ticks) / ticks)
        samples["in_process"].append(bench.in_process_s(ticks) / ticks)
    return {name: float(np.median(values)) for name, values in samples.items()}
