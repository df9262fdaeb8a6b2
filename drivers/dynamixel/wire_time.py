"""The time a Dynamixel sync-read + sync-write cycle takes on the RS-485 wire (Protocol 2.0).

Packet sizes: ROBOTIS e-Manual, Protocol 2.0, "Instruction Packet" / "Status Packet": header
FF FF FD 00 (4) + ID (1) + LENGTH (2) + INSTRUCTION (1) + CRC (2) = 10 bytes around the
parameters; a status packet adds the ERR byte.
"""

from __future__ import annotations

PACKET_OVERHEAD_BYTES = 10
SYNC_PARAMS_HEADER_BYTES = 4  # start address (2) + data length (2)
STATUS_OVERHEAD_BYTES = PACKET_OVERHEAD_BYTES + 1
BITS_PER_BYTE_ON_WIRE = 10  # 8N1: start + 8 data + stop
GOAL_POSITION_BYTES = 4


def sync_cycle_wire_bytes(
    n_devices: int, read_bytes: int, write_bytes: int = GOAL_POSITION_BYTES
) -> int:
    """Bytes on the RS-485 line for one SYNC_READ + its replies + one SYNC_WRITE.

    SYNC_READ (0x82): 10 + 4 + N (the ID list) = 14 + N;
    N status packets of 11 + L bytes each (L = `read_bytes`);
    SYNC_WRITE (0x83): 10 + 4 + N (1 + W) (ID + data per device) = 14 + 5N for W = 4.
    Byte stuffing (an extra 0xFD after any FF FF FD in a packet) is ignored.
    Worked example: 6 x H54, L = 12 (Present Position .. Present Current): 202 bytes.
    """
    if n_devices < 1 or read_bytes < 1 or write_bytes < 1:
        raise ValueError(
            f"need n_devices, read_bytes and write_bytes >= 1, got {n_devices}, {read_bytes}, "
            f"{write_bytes}"
        )
    sync_read = PACKET_OVERHEAD_BYTES + SYNC_PARAMS_HEADER_BYTES + n_devices
    replies = n_devices * (STATUS_OVERHEAD_BYTES + read_bytes)
    sync_write = PACKET_OVERHEAD_BYTES + SYNC_PARAMS_HEADER_BYTES + n_devices * (1 + write_bytes)
    return sync_read + replies + sync_write


def sync_cycle_wire_time_s(
    n_devices: int,
    read_bytes: int,
    baudrate_bps: int,
    return_delay_time_us: float = 0.0,
    write_bytes: int = GOAL_POSITION_BYTES,
) -> float:
    """The cycle's time on the wire: bytes x 10 bits / baud, plus N x Return Delay Time.

    Each device waits its Return Delay Time (item 9, 2 us units) before answering, one after
    the other (e-Manual H54; DynamixelSDK issue #302: 6 x 500 us explained a > 4 ms sync read).
    USB latency and OS scheduling come on top on real hardware.
    """
    if baudrate_bps <= 0 or return_delay_time_us < 0:
        raise ValueError(
            f"need baudrate_bps > 0 and return_delay_time_us >= 0, got {baudrate_bps}, "
            f"{return_delay_time_us}"
        )
    n_bytes = sync_cycle_wire_bytes(n_devices, read_bytes, write_bytes)
    return n_bytes * BITS_PER_BYTE_ON_WIRE / baudrate_bps + n_devices * return_delay_time_us * 1e-6
