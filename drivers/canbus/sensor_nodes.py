"""What the CAN sensor reader knows of each node: its record (configuration plus what `open()`
learned), the NMT states its heartbeats report, and the error every failure raises.

Shared by the bring-up (`node_bringup.py`), the receive path (`frame_receive.py`) and the
reader (`link_encoders.py`).
"""

from __future__ import annotations

from dataclasses import dataclass

import canopen
import numpy as np
from canopen.nmt import NMT_STATES

from drivers.canbus.config import ForceSensorConfig, ForceTorqueSensorConfig, LinkEncoderConfig
from drivers.joint_bus import BusError

HEARTBEAT_OPERATIONAL = 0x05
HEARTBEAT_BOOTUP = 0x00
HEARTBEAT_PRE_OPERATIONAL = 0x7F
UNKNOWN_STATE = 0xFF
FORCE_TORQUE_CHANNELS = 6


class CanDeviceError(BusError):
    """A CAN sensor node could not be opened or read (the message names node and bus)."""


@dataclass
class SensorDevice:
    """One node as the reader knows it (configuration plus what open() learned)."""

    label: str
    config: LinkEncoderConfig | ForceSensorConfig | ForceTorqueSensorConfig
    node: canopen.RemoteNode
    tpdo_cob_id: int = 0
    tpdo_cob_ids: tuple[int, ...] = ()  # every TPDO the node answers a SYNC with
    single_turn: bool = False
    newtons_per_count: float = 1.0
    si_per_count: np.ndarray | None = None  # force/torque sensor: per channel, N or N m

    @property
    def is_encoder(self) -> bool:
        return isinstance(self.config, LinkEncoderConfig)

    @property
    def is_force_torque(self) -> bool:
        return isinstance(self.config, ForceTorqueSensorConfig)


def state_name(state: int) -> str:
    """An NMT state code as canopen names it ("OPERATIONAL"), "UNKNOWN" if never reported."""
    if state == UNKNOWN_STATE:
        return "UNKNOWN"
    return NMT_STATES.get(state, f"0x{state:02X}")
