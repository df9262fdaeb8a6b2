"""Byte-exact emulation of a chain of DYNAMIXEL PRO actuators (Protocol 2.0) on a pty: every
model of the family with a published control table, mixed on one line as the user likes.

Layers, one job each:
- `protocol`: CRC, byte stuffing, packet building, the streaming `PacketParser`;
- `models`: the family's figures (model numbers, units, limits, defaults) with their sources;
- `control_table`: each model's control table as data (`device_model`);
- `device`: `DynamixelProDevice`, one actuator's table and instruction semantics, plus the
  firmware-side API a physics model drives;
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
    DeviceModel,
    device_model,
)
from sim_backend.dynamixel.device import DynamixelProDevice, H54Device
from sim_backend.dynamixel.faults import FaultCounts, LineFaults
from sim_backend.dynamixel.line import DynamixelLine, serve_forever
from sim_backend.dynamixel.models import FAMILY, Firmware, ModelFigures
from sim_backend.dynamixel.protocol import ErrorCode, Instruction, PacketParser, crc16

__all__ = [
    "BAUD_RATE_BPS",
    "H54_ITEMS",
    "H54_LAYOUT",
    "MODEL_NUMBER_H54_200_S500_R",
    "ControlItem",
    "DeviceModel",
    "DynamixelChain",
    "DynamixelProDevice",
    "DynamixelLine",
    "FaultCounts",
    "ErrorCode",
    "FAMILY",
    "Firmware",
    "H54Device",
    "Instruction",
    "LineFaults",
    "ModelFigures",
    "PacketParser",
    "crc16",
    "device_model",
    "serve_forever",
]
