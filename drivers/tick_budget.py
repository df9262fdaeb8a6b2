"""What one tick costs on the wires of a real robot, from the bus configuration alone.

A tick (drivers/dynamixel_can_bus.py) is: SYNC on every CAN channel, the TPDOs that answer it,
one Dynamixel sync read per chain and one sync write per chain. Their times on the wire:

- CAN 2.0A data frame with n data bytes (ISO 11898-1): SOF 1 + identifier 11 + RTR 1 + IDE 1
  + r0 1 + DLC 4 + 8n + CRC 15 + CRC delimiter 1 + ACK 2 + EOF 7 = 44 + 8n bits, + 3 bits of
  interframe space; bit stuffing adds at most one bit per four of the 34 + 8n bits from SOF to
  the CRC (worst case). Per tick: SYNC (0 bytes), a 4-byte TPDO per link encoder
  (0x6004 position value) and per 1-axis force sensor (0x9130:01), two 6-byte TPDOs per
  force/torque sensor (0x7130:1-3, :4-6).
- Dynamixel Protocol 2.0 at 8N1 (drivers/dynamixel/wire_time.py): the sync read and its
  replies (the state block, drivers/dynamixel/state_block.py), the sync write of the goals.
- The USB-serial adapter: it hands received bytes to the host when its latency timer expires
  (FTDI: 16 ms by default, 1 ms when set; the configuration's `latency_timer_ms`), so every
  transaction that waits for an answer pays up to that much again.

Sequential (SYNC, wait for every TPDO, then the sync read) the parts add up; the bus overlaps
the sync read with the TPDOs' arrival, so the tick takes the longer of the two, plus the write.
Channels and chains on separate adapters run side by side; the longest of each counts.
"""

from __future__ import annotations

from dataclasses import dataclass

from drivers.dynamixel.state_block import STATE_BLOCK_ITEMS
from drivers.dynamixel.wire_time import (
    BITS_PER_BYTE_ON_WIRE,
    GOAL_POSITION_BYTES,
    PACKET_OVERHEAD_BYTES,
    STATUS_OVERHEAD_BYTES,
    SYNC_PARAMS_HEADER_BYTES,
)
from drivers.dynamixel_can_bus import CanChannelConfig, DynamixelCanBusConfig

CAN_FRAME_FIXED_BITS = 44
CAN_INTERFRAME_BITS = 3
CAN_STUFFED_SPAN_FIXED_BITS = 34  # SOF .. CRC, the span bit stuffing applies to
ENCODER_TPDO_BYTES = 4
FORCE_TPDO_BYTES = 4
FORCE_TORQUE_TPDO_BYTES = 6
# H54 state block sizes (e-Manual H54 control table), in the order of STATE_BLOCK_ITEMS.
_STATE_ITEM_BYTES = {
    "Present Position": 4,
    "Present Velocity": 4,
    "Present Current": 2,
    "Present Input Voltage": 2,
    "Hardware Error Status": 1,
    "Torque Enable": 1,
    "Present Temperature": 1,
}
STATE_BLOCK_BYTES = sum(_STATE_ITEM_BYTES[name] for name in STATE_BLOCK_ITEMS)


def can_frame_bits(data_bytes: int, *, worst_case_stuffing: bool = True) -> int:
    """Bits one CAN 2.0A data frame occupies on the bus, interframe space included."""
    if not 0 <= data_bytes <= 8:
        raise ValueError(f"a classic CAN frame carries 0..8 bytes, got {data_bytes}")
    bits = CAN_FRAME_FIXED_BITS + 8 * data_bytes + CAN_INTERFRAME_BITS
    if worst_case_stuffing:
        bits += (CAN_STUFFED_SPAN_FIXED_BITS + 8 * data_bytes - 1) // 4
    return bits


def channel_frames(channel: CanChannelConfig) -> list[int]:
    """Data bytes of every frame one tick puts on a channel: SYNC, then the TPDOs."""
    frames = [0]
    frames += [ENCODER_TPDO_BYTES] * len(channel.encoders)
    if channel.force_sensor is not None:
        frames.append(FORCE_TPDO_BYTES)
    frames += [FORCE_TORQUE_TPDO_BYTES] * (2 * len(channel.force_torque_sensors))
    return frames


@dataclass(frozen=True)
class TickBudget:
    """One tick's wire times [s] (see the module docstring)."""

    can_s: float  # SYNC + TPDOs, the busiest channel (worst-case stuffing)
    sync_read_s: float  # the sync read and every reply, the busiest chain
    sync_write_s: float  # the goals' sync write, the busiest chain
    usb_latency_s: float  # the adapter's latency timer, paid once by the sync read
    period_s: float

    @property
    def sequential_s(self) -> float:
        return self.can_s + self.sync_read_s + self.usb_latency_s + self.sync_write_s

    @property
    def overlapped_s(self) -> float:
        return max(self.can_s, self.sync_read_s + self.usb_latency_s) + self.sync_write_s

    def text(self) -> str:
        ms = 1e3
        return (
            f"CAN {self.can_s * ms:.2f} ms (SYNC + TPDOs), sync read {self.sync_read_s * ms:.2f}"
            f" ms + USB latency {self.usb_latency_s * ms:.2f} ms, sync write "
            f"{self.sync_write_s * ms:.2f} ms: sequential {self.sequential_s * ms:.2f} ms, "
            f"overlapped {self.overlapped_s * ms:.2f} ms of the {self.period_s * ms:g} ms period"
        )


def tick_budget(config: DynamixelCanBusConfig, period_s: float) -> TickBudget:
    """The tick's wire times for this bus (no device is contacted)."""
    can_s = 0.0
    for channel in config.can_channels:
        bitrate = float(channel.bus_kwargs.get("bitrate") or 1_000_000)
        bits = sum(can_frame_bits(n) for n in channel_frames(channel))
        can_s = max(can_s, bits / bitrate)
    read_s = write_s = latency_s = 0.0
    for chain in config.chains:
        n = len(chain.joints)
        bit_s = BITS_PER_BYTE_ON_WIRE / chain.baudrate
        request = PACKET_OVERHEAD_BYTES + SYNC_PARAMS_HEADER_BYTES + n
        replies = n * (STATUS_OVERHEAD_BYTES + STATE_BLOCK_BYTES)
        delays = n * chain.return_delay_time_us * 1e-6
        read_s = max(read_s, (request + replies) * bit_s + delays)
        goals = PACKET_OVERHEAD_BYTES + SYNC_PARAMS_HEADER_BYTES + n * (1 + GOAL_POSITION_BYTES)
        write_s = max(write_s, goals * bit_s)
        latency_s = max(latency_s, chain.latency_timer_ms * 1e-3)
    return TickBudget(can_s, read_s, write_s, latency_s, period_s)
