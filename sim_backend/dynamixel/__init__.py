"""Byte-exact emulation of a Dynamixel Pro H54-200-S500-R chain (Protocol 2.0) on a pty.

Layers, one job each:
- `protocol`: CRC, byte stuffing, packet building, the streaming `PacketParser`;
- `control_table`: the H54 control table as data;
- `device`: `H54Device`, one actuator's table and instruction semantics, plus the firmware-side
  API a physics model drives;
- `chain`: `DynamixelChain`, many IDs on one line (broadcast, sync/bulk, timing model);
- `faults`: `LineFaults`, injectable line faults;
- `line`: `DynamixelLine`, the pty endpoint for an event loop, and `serve_forever`;
- `testing`: `spawn_emulated_chain`, a chain in a child process for tests with dynamixel-sdk.
"""

from sim_backend.dynamixel.chain import DynamixelChain
from sim_backend.dynamixel.control_table import (
    BAUD_RATE_BPS,
    H54_ITEMS,
    H54_LAYOUT,
    MODEL_NUMBER_H54_200_S500_R,
    ControlItem,
)
from sim_backend.dynamixel.device import H54Device
from sim_backend.dynamixel.faults import FaultCounts, LineFaults
from sim_backend.dynamixel.line import DynamixelLine, serve_forever
from sim_backend.dynamixel.protocol import ErrorCode, Instruction, PacketParser, crc16

__all__ = [
    "BAUD_RATE_BPS",
    "H54_ITEMS",
    "H54_LAYOUT",
    "MODEL_NUMBER_H54_200_S500_R",
    "ControlItem",
    "DynamixelChain",
    "DynamixelLine",
    "FaultCounts",
    "ErrorCode",
    "H54Device",
    "Instruction",
    "LineFaults",
    "PacketParser",
    "crc16",
    "serve_forever",
]
