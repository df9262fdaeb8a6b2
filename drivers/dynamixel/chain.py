"""`DynamixelChain`: a chain of DYNAMIXEL PROs on one port, over the unmodified dynamixel-sdk.
The devices may be of several models of the family (each joint's model: its configuration,
checked by PING at `open()`); each converts in its own units.

One tick is one SYNC_READ of the indirect-mapped state block (`state_block.py`) and one
SYNC_WRITE of Goal Position (4 bytes: 596 on the PRO, 564 on PRO+): two bus transactions for any
number of devices; a chain that mixes the PRO and PRO+ layouts writes one SYNC_WRITE per layout
(`transfer_groups.py` says why).

This module holds the chain's state and its lifecycle: `open()` identifies and configures the
devices (the steps in `configure.py`), `close()` releases the port. The per-tick transactions
are in `sync_transfer.py`, torque on/off, REBOOT and the hardware error status in
`torque_control.py`.

The SDK is not thread-safe: use a chain from one thread.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
from dynamixel_sdk import GroupSyncRead, PacketHandler

from drivers.dynamixel import configure
from drivers.dynamixel.config import DynamixelChainConfig, DynamixelJointConfig
from drivers.dynamixel.device_io import DeviceIO
from drivers.dynamixel.errors import EepromChangeRefused
from drivers.dynamixel.port import LowLatencyPortHandler, open_port
from drivers.dynamixel.state import DeviceInfo, DynamixelState, HardwareErrorStatus
from drivers.dynamixel.state_block import STATE_BLOCK_ITEMS, DirectStateSpan, StateBlockLayout
from drivers.dynamixel.sync_transfer import SyncTransfer
from drivers.dynamixel.torque_control import TorqueControl
from drivers.dynamixel.transfer_groups import ReadGroup, read_groups, write_groups
from drivers.dynamixel.units import current_limit_raw_to_a
from drivers.joint_bus import BusError
from drivers.peer_wait import PeerWait

__all__ = [
    "DeviceInfo",
    "DynamixelChain",
    "DynamixelChainConfig",
    "DynamixelJointConfig",
    "DynamixelState",
    "HardwareErrorStatus",
]


class DynamixelChain(SyncTransfer, TorqueControl):
    """A chain of actuators on one port, of one model or several (see the module docstring).

    Lifecycle: `open()` (identify, configure, never enables torque), `enable()`, then per tick
    `read_state()` and `write_goals()`, `disable()`, `close()` (does not change torque).
    IDs in `enable`/`disable`/`reboot` are Dynamixel IDs; arrays are in `config.joints` order.
    """

    def __init__(self, config: DynamixelChainConfig, patience: PeerWait | None = None) -> None:
        self.config = config
        self.patience = patience  # a device that is a process here: drivers/peer_wait.py
        self.spec = config.spec  # the chain's default model
        self.specs = config.specs  # each joint's, in joint order
        self.units = config.units  # each joint's units as arrays (ChainUnits)
        self.layouts = tuple(
            StateBlockLayout(spec, config.indirect_first_index) for spec in self.specs
        )
        self.layout = self.layouts[0]
        self._joints = config.joints
        self._ids = config.dxl_ids
        self._spec_of = dict(zip(self._ids, self.specs, strict=True))
        self._index_of = {dxl_id: index for index, dxl_id in enumerate(self._ids)}
        self._labels = {joint.dxl_id: joint.label for joint in self._joints}
        self._direction = np.array([joint.direction for joint in self._joints], dtype=np.float64)
        self._offset_rad = np.array([joint.offset_rad for joint in self._joints])
        self._min_rad = np.array([joint.min_position_rad for joint in self._joints])
        self._max_rad = np.array([joint.max_position_rad for joint in self._joints])
        self._device_limits = {
            joint.dxl_id: joint.device_position_limits_pulses(spec.units)
            for joint, spec in zip(self._joints, self.specs, strict=True)
        }
        self._packet = PacketHandler(2.0)
        self._port: LowLatencyPortHandler | None = None
        self._io: DeviceIO | None = None
        # The sync reads (one per state-block geometry, made at open) and sync writes (one per
        # Goal Position address; their parameters built once, each tick changes only the goal
        # bytes): one each unless the chain mixes layouts (transfer_groups.py).
        self._read_groups: list[ReadGroup] = []
        self._request_result: int | None = None  # request_state() sent, replies not collected
        self._write_groups = write_groups(self.specs, self._ids)
        self._writes_goals = False  # open and not read-only
        self._raw = np.zeros((len(self._ids), len(STATE_BLOCK_ITEMS)), dtype=np.int64)
        self.devices: tuple[DeviceInfo, ...] = ()
        self.read_only = False
        # Read-only on devices without the state-block map: the span reads (DirectStateSpan).
        self._direct = False

    # ----------------------------------------------------------------------------- properties

    @property
    def dxl_ids(self) -> tuple[int, ...]:
        return self._ids

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(joint.name or f"id{joint.dxl_id}" for joint in self._joints)

    @property
    def is_open(self) -> bool:
        return self._port is not None

    @property
    def port_handler(self) -> LowLatencyPortHandler:
        """The SDK port (for tools such as the bus benchmark; same thread only)."""
        return self._require_io().port

    @property
    def packet_handler(self) -> PacketHandler:
        return self._packet

    @property
    def port_failure(self) -> str | None:
        """The OS error with which the port failed (device unplugged, emulator gone), or None
        while it works. After a failure every call raises `PortGoneError` and sends nothing."""
        return self._port.failure if self._port is not None else None

    # ------------------------------------------------------------------------------ lifecycle

    def open(self, *, allow_torque_off: bool = False, read_only: bool = False) -> None:
        """Open the port, identify every device, configure what differs. Never enables torque.

        read_only=True: identify and read, write nothing at all (a monitor, a calibration):
        what the configuration would change is only recorded (`DeviceInfo.eeprom_changes`), the
        Status Return Level must already answer READs, and `write_goals`, `enable`, `disable`
        and `reboot` raise `BusError`. Where a device lacks the state-block map, the state is
        read from its contiguous RAM span instead (`DirectStateSpan`).

        Identification: PING each ID and check its model number; any missing ID or wrong model
        raises one `BusError` naming them all, the port and the baud rate.
        Configuration (only where the device differs): Status Return Level 2 (RAM; the driver
        relies on replies), Operating Mode 3 (position), Return Delay Time, Max/Min Position
        Limit from the joint range, Torque Limit if given, the indirect-address map of the state
        block (all EEPROM), and the RAM gains if given. A device with torque ON that needs an
        EEPROM change is refused (`EepromChangeRefused`: dropping torque would drop the link)
        unless `allow_torque_off=True`; then its torque is turned off first and stays off.
        """
        if self._port is not None:
            raise BusError(f"Dynamixel chain on {self.config.port} is already open")
        self._port = open_port(
            self.config.port,
            self.config.baudrate,
            latency_timer_ms=self.config.latency_timer_ms,
            timeout_margin_ms=self.config.timeout_margin_ms,
            patience=self.patience,
        )
        self._io = DeviceIO(
            self._port,
            self._packet,
            labels=self._labels,
            where=f"{self.config.port} at {self.config.baudrate} bps",
        )
        self.read_only = read_only
        self._direct = False
        try:
            self._open_devices(self._io, allow_torque_off)
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        """Close the port. Does not change torque (the caller decides). Safe to call twice."""
        port, self._port = self._port, None
        self._io = None
        self._read_groups = []
        self._request_result = None
        self._writes_goals = False
        self._direct = False
        if port is not None and port.is_open:
            port.closePort()

    def __enter__(self) -> DynamixelChain:
        self.open()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    # ------------------------------------------------------------------------------ internals
    def _settle(self) -> DeviceIO:
        """The port, for a new transaction: the replies of a SYNC_READ that was sent and not
        collected (an exception between `request_state` and `receive_state`) are collected
        first, so that the transaction does not take them for its own status packets."""
        if self._request_result is not None:
            self.receive_state()
        return self._require_io()

    def _require_writable(self, what: str) -> DeviceIO:
        io = self._settle()
        if self.read_only:
            raise BusError(
                f"Dynamixel chain on {self.config.port} was opened read-only: {what} refused"
            )
        return io

    def _require_io(self) -> DeviceIO:
        if self._io is None:
            raise BusError(f"Dynamixel chain on {self.config.port} is not open; call open() first")
        # The chain is used from one thread, so a transaction in progress now can only be one
        # that an exception (Ctrl-C in the SDK's busy-wait) interrupted: the SDK would refuse
        # every later call with "Port is in use!". Release its flag.
        self._io.port.is_using = False
        return self._io

    def _select(self, ids: Iterable[int] | None) -> tuple[int, ...]:
        if ids is None:
            return self._ids
        selected = tuple(ids)
        unknown = [dxl_id for dxl_id in selected if dxl_id not in self._index_of]
        if unknown:
            raise ValueError(f"IDs {unknown} are not in this chain (IDs {list(self._ids)})")
        return selected

    def _open_devices(self, io: DeviceIO, allow_torque_off: bool) -> None:
        found = configure.identify(io, self._spec_of)
        if not self.read_only:
            for dxl_id in self._ids:
                configure.ensure_status_return_level(io, dxl_id, self._spec_of[dxl_id])
        plans = {
            joint.dxl_id: configure.eeprom_plan(io, joint, self.config, layout)
            for joint, layout in zip(self._joints, self.layouts, strict=True)
        }
        torque_on = {
            dxl_id: io.read_item(dxl_id, self._spec_of[dxl_id].item("Torque Enable")) != 0
            for dxl_id in self._ids
        }
        if self.read_only:
            # the map is an EEPROM write: where a device lacks it, read the plain spans instead
            self._direct = any(
                write.address == layout.indirect_address_start
                for layout, joint in zip(self.layouts, self._joints, strict=True)
                for write in plans[joint.dxl_id]
            )
        else:
            self._configure(io, plans, torque_on, allow_torque_off)
        self._finish_open(io, found, plans, torque_on)

    def _configure(
        self,
        io: DeviceIO,
        plans: dict[int, list[configure.EepromWrite]],
        torque_on: dict[int, bool],
        allow_torque_off: bool,
    ) -> None:
        blocked = [dxl_id for dxl_id in self._ids if plans[dxl_id] and torque_on[dxl_id]]
        if blocked and not allow_torque_off:
            details = "; ".join(
                f"{io.label(dxl_id)} needs "
                + ", ".join(write.description for write in plans[dxl_id])
                for dxl_id in blocked
            )
            raise EepromChangeRefused(
                "EEPROM items can only be written with torque off, and these devices have "
                f"torque ON: {details}. Turning torque off would drop the link: support it, then "
                "open with allow_torque_off=True (torque then stays off), or turn torque off "
                "yourself first. Nothing was written."
            )
        for dxl_id in self._ids:
            if not plans[dxl_id]:
                continue
            if torque_on[dxl_id]:
                torque_item = self._spec_of[dxl_id].item("Torque Enable")
                io.write_item(dxl_id, torque_item, 0)
                torque_on[dxl_id] = io.read_item(dxl_id, torque_item) != 0
            configure.apply_eeprom_plan(io, dxl_id, plans[dxl_id])
        for joint in self._joints:
            configure.apply_ram_settings(io, joint, self._spec_of[joint.dxl_id])

    def _finish_open(
        self,
        io: DeviceIO,
        found: dict[int, tuple[int, int]],
        plans: dict[int, list[configure.EepromWrite]],
        torque_on: dict[int, bool],
    ) -> None:
        spec_of = self._spec_of
        self.devices = tuple(
            DeviceInfo(
                dxl_id=dxl_id,
                model_number=found[dxl_id][0],
                firmware_version=found[dxl_id][1],
                shutdown_mask=io.read_item(dxl_id, spec_of[dxl_id].item("Shutdown")),
                hardware_error=self.read_hardware_error(dxl_id).bits,
                torque_enabled=torque_on[dxl_id],
                eeprom_changes=tuple(write.description for write in plans[dxl_id]),
                current_limit_a=current_limit_raw_to_a(
                    io.read_item(dxl_id, spec_of[dxl_id].item("Torque Limit")),
                    spec_of[dxl_id].units,
                ),
                model_name=spec_of[dxl_id].model_name,
            )
            for dxl_id in self._ids
        )
        blocks = (
            [DirectStateSpan(spec) for spec in self.specs] if self._direct else list(self.layouts)
        )
        self._read_groups = read_groups(blocks, self._ids)
        for group in self._read_groups:
            group.sync_read = GroupSyncRead(io.port, self._packet, group.data_start, group.size)
            for dxl_id in group.ids:
                group.sync_read.addParam(dxl_id)
        self._writes_goals = True
