"""Bus benchmark (`hil bench bus`): the chain's tick against a bare SDK loop, side by side.

Per cycle, interleaved (alternating which goes first) so both see the same machine load:
- chain: `read_state()` (one SYNC_READ of the indirect state block + SI conversion) then
  `write_goals()` (one SYNC_WRITE of Goal Position);
- bare: the textbook SDK loop: `GroupSyncRead(611, 12)` (Present Position .. Present Current)
  `txRxPacket()` + `getData()` of the three items, then `GroupSyncWrite(596, 4).txPacket()`.
Both write the goals read at the start (hold position), so the benchmark does not move a
joint whose torque is on. It does not change torque.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from dynamixel_sdk import COMM_SUCCESS, GroupSyncRead, GroupSyncWrite

from drivers.dynamixel.chain import DynamixelChain
from drivers.dynamixel.units import rad_to_position
from drivers.joint_bus import BusError
from drivers.timing import DurationStats


@dataclass(frozen=True)
class CycleStats(DurationStats):
    """Wall time of one read+write cycle [s]; failures: invalid reads."""

    failures: int = 0

    @property
    def cycles(self) -> int:
        return self.count

    @classmethod
    def from_samples(cls, durations_s: np.ndarray, failures: int) -> CycleStats:
        stats = DurationStats.of(durations_s)
        return cls(**vars(stats), failures=failures)


@dataclass(frozen=True)
class BusBenchResult:
    n_devices: int
    baudrate: int
    chain: CycleStats
    bare: CycleStats

    def summary(self) -> str:
        def line(name: str, stats: CycleStats) -> str:
            return (
                f"{name}: median {stats.median_s * 1e3:.3f} ms, p90 {stats.p90_s * 1e3:.3f} ms, "
                f"max {stats.max_s * 1e3:.3f} ms, failed reads {stats.failures}/{stats.cycles}"
            )

        return (
            f"{self.n_devices} device(s) at {self.baudrate} bps\n"
            f"  {line('chain read_state+write_goals', self.chain)}\n"
            f"  {line('bare GroupSyncRead+GroupSyncWrite', self.bare)}"
        )


def bench_bus(chain: DynamixelChain, cycles: int = 1000, warmup: int = 50) -> BusBenchResult:
    """Time `cycles` interleaved cycles of both loops on an open chain (after `warmup`)."""
    if cycles < 1 or warmup < 0:
        raise ValueError(f"need cycles >= 1 and warmup >= 0, got {cycles}, {warmup}")
    port = chain.port_handler  # raises if the chain is not open
    packet = chain.packet_handler
    state = chain.read_state()
    if not state.all_valid:
        raise BusError("bench: the first read failed: " + "; ".join(state.errors))
    goals_rad = state.position_rad.copy()
    if chain.config.mixed:  # the bare loop is the textbook one: one model's addresses
        raise BusError("bench: the bare SDK loop needs a chain of one model; this one mixes them")
    spec = chain.specs[0]
    position = spec.item("Present Position")
    velocity = spec.item("Present Velocity")
    current = spec.item("Present Current")
    # Present Position .. Present Current (PRO: 611..622; PRO+: 574..583, the other order)
    first = min(position.address, current.address)
    block_length = max(position.address + position.size, current.address + current.size) - first
    bare_read = GroupSyncRead(port, packet, first, block_length)
    bare_write = GroupSyncWrite(port, packet, spec.item("Goal Position").address, 4)
    directions = np.array([joint.direction for joint in chain.config.joints])
    offsets = np.array([joint.offset_rad for joint in chain.config.joints])
    goal_pulses = rad_to_position(goals_rad, chain.units, directions, offsets)
    for dxl_id, pulses in zip(chain.dxl_ids, goal_pulses.tolist(), strict=True):
        bare_read.addParam(dxl_id)
        bare_write.addParam(dxl_id, pulses.to_bytes(4, "little", signed=True))

    def chain_cycle() -> bool:
        ok = chain.read_state().all_valid
        chain.write_goals(goals_rad)
        return ok

    def bare_cycle() -> bool:
        ok = bare_read.txRxPacket() == COMM_SUCCESS
        for dxl_id in chain.dxl_ids:
            bare_read.getData(dxl_id, position.address, position.size)
            bare_read.getData(dxl_id, velocity.address, velocity.size)
            bare_read.getData(dxl_id, current.address, current.size)
        if bare_write.txPacket() != COMM_SUCCESS:
            raise BusError("bench: bare sync write failed")
        return ok

    total = warmup + cycles
    durations_s = {chain_cycle: np.empty(total), bare_cycle: np.empty(total)}
    failures = {chain_cycle: 0, bare_cycle: 0}
    for cycle in range(total):
        # Alternate which loop goes first, so neither always follows the other.
        for run in (chain_cycle, bare_cycle) if cycle % 2 == 0 else (bare_cycle, chain_cycle):
            start = time.perf_counter()
            ok = run()
            durations_s[run][cycle] = time.perf_counter() - start
            if cycle >= warmup:
                failures[run] += not ok
    return BusBenchResult(
        n_devices=len(chain.dxl_ids),
        baudrate=chain.config.baudrate,
        chain=CycleStats.from_samples(durations_s[chain_cycle][warmup:], failures[chain_cycle]),
        bare=CycleStats.from_samples(durations_s[bare_cycle][warmup:], failures[bare_cycle]),
    )
