"""CiA 301 (CANopen application layer) constants used by the emulated nodes.

Sources: CiA 301 predefined connection set and NMT/SDO services as summarised in the
CANopenNode object dictionary (`minimal_project.xdd`) and vendor manuals (Beckhoff FC5101,
Datalogic AMT58); SDO abort codes as listed by the `canopen` package
(`canopen/sdo/constants.py`, `canopen/sdo/exceptions.py`).
"""

from __future__ import annotations

import enum

# Predefined connection set: function code base, COB-ID = base + node ID.
NMT_COB_ID = 0x000
SYNC_COB_ID = 0x080
EMCY_COB_ID_BASE = 0x080
TPDO_COB_ID_BASES = (0x180, 0x280, 0x380, 0x480)
SDO_RESPONSE_COB_ID_BASE = 0x580  # server -> client
SDO_REQUEST_COB_ID_BASE = 0x600  # client -> server
HEARTBEAT_COB_ID_BASE = 0x700  # heartbeat and boot-up

# PDO COB-ID entry (0x18xx:01) bits.
PDO_COB_ID_INVALID = 1 << 31
PDO_COB_ID_NO_RTR = 1 << 30
PDO_COB_ID_EXTENDED = 1 << 29
STANDARD_ID_MASK = 0x7FF

# Transmission types (0x18xx:02).
TRANSMISSION_ACYCLIC_SYNC = 0
TRANSMISSION_SYNC_MAX = 240  # 1..240: every n-th SYNC
TRANSMISSION_EVENT_MANUFACTURER = 254
TRANSMISSION_EVENT_PROFILE = 255

# Object dictionary areas.
COMMUNICATION_AREA = range(0x1000, 0x2000)


class NmtState(enum.IntEnum):
    """NMT states as coded in the heartbeat byte (0x00 is the boot-up frame)."""

    INITIALISING = 0x00
    STOPPED = 0x04
    OPERATIONAL = 0x05
    PRE_OPERATIONAL = 0x7F


class NmtCommand(enum.IntEnum):
    """NMT command specifiers (frame 0x000: [command, node ID or 0 for all])."""

    START = 0x01
    STOP = 0x02
    ENTER_PRE_OPERATIONAL = 0x80
    RESET_NODE = 0x81
    RESET_COMMUNICATION = 0x82


class SdoAbortCode(enum.IntEnum):
    """SDO abort codes the emulated SDO server sends."""

    TOGGLE_NOT_ALTERNATED = 0x0503_0000
    INVALID_COMMAND_SPECIFIER = 0x0504_0001
    READ_WRITE_ONLY = 0x0601_0001
    WRITE_READ_ONLY = 0x0601_0002
    OBJECT_DOES_NOT_EXIST = 0x0602_0000
    LENGTH_MISMATCH = 0x0607_0010
    LENGTH_TOO_HIGH = 0x0607_0012
    LENGTH_TOO_LOW = 0x0607_0013
    SUBINDEX_DOES_NOT_EXIST = 0x0609_0011
    VALUE_RANGE_EXCEEDED = 0x0609_0030
    VALUE_TOO_HIGH = 0x0609_0031
    VALUE_TOO_LOW = 0x0609_0032
    GENERAL_ERROR = 0x0800_0000
    DEVICE_STATE = 0x0800_0022
