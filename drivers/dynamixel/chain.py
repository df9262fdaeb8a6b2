"""`DynamixelChain`: a chain of Dynamixel Pro H54s on one port, over the unmodified dynamixel-sdk.

One tick is one SYNC_READ of the indirect-mapped state block (`state_block.py`) and one
SYNC_WRITE of Goal Position (596, 4 bytes): two bus transactions for any number of devices.

Protocol facts (ROBOTIS e-Manual, Protocol 2.0 and H54-200-S500-R pages):
- A SYNC_WRITE gets no reply: a goal outside Min/Max Position Limit (40/36) would be dropped
  with a Data Limit error nobody sees, so goals are checked here before sending.
- A hardware error whose bit is set in Shutdown (48) clears Torque Enable (562), sets the Alert
  bit in every status packet and latches Hardware Error Status (892); only a REBOOT (0x08)
  clears it.
- In a SYNC_READ the devices answer in the order listed; if one stays silent the ones after it
  do not answer either (ROBOTIS maintainer, DynamixelSDK issue #364).

Reading the sync-read replies: the SDK's `GroupSyncRead.rxPacket()` drops each device's ERR byte
and, if any device fails, makes `getData` return 0 for all of them; its `readRx()` discards a
reply whose ID it does not expect next. `read_state()` therefore sends with
`GroupSyncRead.txPacket()` and collects the status packets with the SDK's public
`PacketHandler.rxPacket()` (framing, CRC check, unstuffing) under the single timeout
`syncReadTx` set for the group, matching them by ID: each device keeps its own validity and its
Alert bit, and a lost reply costs only that device. The SDK is used unmodified.

The SDK is not thread-safe: use a chain from one thread.
"""

from __future__ import annotations

import time
from collections.abc import Iterable

import numpy as np
from dynamixel_sdk import (
    COMM_RX_TIMEOUT,
    COMM_SUCCESS,
    GroupSyncRead,
    PacketHandler,
)

from drivers.dynamixel import configure
from drivers.dynamixel.config import DynamixelChainConfig, DynamixelJointConfig
from drivers.dynamixel.device_io import ERRBIT_ALERT, ERROR_NUMBER_MASK, DeviceIO
from drivers.dynamixel.errors import (
    DeviceShutdownError,
    DynamixelReplyError,
    EepromChangeRefused,
    PortGoneError,
)
from drivers.dynamixel.hardware_error import HardwareError
from drivers.dynamixel.port import LowLatencyPortHandler, open_port
from drivers.dynamixel.state import DeviceInfo, DynamixelState, HardwareErrorStatus
from drivers.dynamixel.state_block import STATE_BLOCK_ITEMS, DirectStateSpan, StateBlockLayout
from drivers.dynamixel.units import (
    current_a_to_torque_estimate_nm,
    current_limit_raw_to_a,
    current_to_a,
    input_voltage_to_v,
    position_to_rad,
    rad_to_position,
    velocity_to_rad_s,
)
from drivers.joint_bus import BusError

__all__ = [
    "DeviceInfo",
    "DynamixelChain",
    "DynamixelChainConfig",
    "DynamixelJointConfig",
    "DynamixelState",
    "HardwareErrorStatus",
]

REBOOT_POLL_INTERVAL_S = 0.01  # pause between PING rounds while devices reboot

# Status packet layout after the SDK removed the stuffing (e-Manual Protocol 2.0, "Status Packet"):
# FF FF FD 00 | ID | LEN_L LEN_H | 0x55 | ERR | data... | CRC_L CRC_H
PKT_ID, PKT_LENGTH_L, PKT_LENGTH_H, PKT_ERROR, PKT_DATA = 4, 5, 6, 8, 9

# Column of each value in the decoded state block.
_POSITION = STATE_BLOCK_ITEMS.index("Present Position")
_VELOCITY = STATE_BLOCK_ITEMS.index("Present Velocity")
_CURRENT = STATE_BLOCK_ITEMS.index("Present Current")
_VOLTAGE = STATE_BLOCK_ITEMS.index("Present Input Voltage")
_HW_ERROR = STATE_BLOCK_ITEMS.index("Hardware Error Status")
_TORQUE = STATE_BLOCK_ITEMS.index("Torque Enable")
_TEMPERATURE = STATE_BLOCK_ITEMS.index("Present Temperature")


class DynamixelChain:
    """A chain of actuators of one model on one port (see the module docstring).

    Lifecycle: `open()` (identify, configure, never enables torque), `enable()`, then per tick
    `read_state()` and `write_goals()`, `disable()`, `close()` (does not change torque).
    IDs in `enable`/`disable`/`reboot` are Dynamixel IDs; arrays are in `config.joints` order.
    """

    def __init__(self, config: DynamixelChainConfig) -> None:
        self.config = config
        self.spec = config.spec
        self.units = self.spec.units
        self.layout = StateBlockLayout(self.spec, config.indirect_first_index)
        self._decoder = self.layout.decoder()
        self._block_size = self.layout.size
        self._joints = config.joints
        self._ids = config.dxl_ids
        self._index_of = {dxl_id: index for index, dxl_id in enumerate(self._ids)}
        self._labels = {joint.dxl_id: joint.label for joint in self._joints}
        self._direction = np.array([joint.direction for joint in self._joints], dtype=np.float64)
        self._offset_rad = np.array([joint.offset_rad for joint in self._joints])
        self._min_rad = np.array([joint.min_position_rad for joint in self._joints])
        self._max_rad = np.array([joint.max_position_rad for joint in self._joints])
        self._device_limits = {
            joint.dxl_id: joint.device_position_limits_pulses(self.units) for joint in self._joints
        }
        self._packet = PacketHandler(2.0)
        self._port: LowLatencyPortHandler | None = None
        self._io: DeviceIO | None = None
        self._sync_read: GroupSyncRead | None = None
        self._request_result: int | None = None  # request_state() sent, replies not collected
        # The SYNC_WRITE's parameters, [ID, 4 bytes of Goal Position] per device, built once:
        # each tick changes only the goal bytes (`write_goals`).
        self._goal_params = np.zeros((len(self._ids), 5), dtype=np.uint8)
        self._goal_params[:, 0] = self._ids
        self._goal_address = self.spec.item("Goal Position").address
        self._writes_goals = False  # open and not read-only
        self._raw = np.zeros((len(self._ids), len(self.layout.items)), dtype=np.int64)
        self.devices: tuple[DeviceInfo, ...] = ()
        self.read_only = False
        # Read-only on devices without the state-block map: the span read (see DirectStateSpan).
        self._direct: DirectStateSpan | None = None
        self._direct_columns = np.array(DirectStateSpan(self.spec).columns, dtype=np.intp)

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
        )
        self._io = DeviceIO(
            self._port,
            self._packet,
            labels=self._labels,
            where=f"{self.config.port} at {self.config.baudrate} bps",
        )
        self.read_only = read_only
        self._decoder = self.layout.decoder()
        try:
            self._open_devices(self._io, allow_torque_off)
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        """Close the port. Does not change torque (the caller decides). Safe to call twice."""
        port, self._port = self._port, None
        self._io = None
        self._sync_read = None
        self._request_result = None
        self._writes_goals = False
        self._direct = None
        if port is not None and port.is_open:
            port.closePort()

    def __enter__(self) -> DynamixelChain:
        self.open()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    # -------------------------------------------------------------------------- the 200 Hz path

    def read_state(self) -> DynamixelState:
        """One SYNC_READ of the state block of every device (see the module docstring):
        `request_state()` then `receive_state()`.

        Never raises for a device that does not answer: its entries are invalid (NaN) and
        `errors` says why. Raises `BusError` if the chain is not open, `PortGoneError` (a
        BusError) if the port itself failed.
        """
        self.request_state()
        return self.receive_state()

    def request_state(self) -> None:
        """Send the SYNC_READ and return at once: the replies travel (wire time, Return Delay
        Time, the adapter's latency timer) while the caller does other work;
        `receive_state()` collects them. The reply timeout runs from here."""
        self._settle()
        sync_read = self._sync_read
        assert sync_read is not None
        self._request_result = sync_read.txPacket()

    def receive_state(self) -> DynamixelState:
        """The replies to the last `request_state()` (see `read_state`)."""
        io = self._require_io()
        result, self._request_result = self._request_result, None
        if result is None:
            raise BusError(f"{self.config.port}: receive_state() without request_state() first")
        raw = self._raw
        valid = np.zeros(len(self._ids), dtype=bool)
        alert = np.zeros(len(self._ids), dtype=bool)
        errors: list[str] = []
        reasons: dict[int, str] = {}  # why a device's entry is invalid, by ID
        if result != COMM_SUCCESS:
            reason = f"sync read not sent: {self._packet.getTxRxResult(result)}"
            errors.append(reason)
            reasons.update(dict.fromkeys(self._ids, reason))
            return self._state_from_raw(raw, valid, alert, errors, reasons)
        size = self._block_size if self._direct is None else self._direct.size
        expected_length = size + 4  # LEN field: INST + ERR + data + CRC(2)
        pending = dict(self._index_of)
        corrupt = 0
        # Replies are matched by ID, so one lost or corrupted reply does not also cost the
        # (valid) replies after it. Each rxPacket call either consumes bytes or reports the
        # group's timeout, so the loop ends; the bound guards against a babbling line.
        for _ in range(2 * len(self._ids) + 2):
            packet, result = self._packet.rxPacket(io.port, False)
            if result == COMM_RX_TIMEOUT:
                break
            if result != COMM_SUCCESS:
                corrupt += 1
                continue
            index = pending.get(packet[PKT_ID])
            error = packet[PKT_ERROR]
            if index is None or (
                not error & ERROR_NUMBER_MASK
                and packet[PKT_LENGTH_L] | (packet[PKT_LENGTH_H] << 8) != expected_length
            ):
                continue  # not a reply to this read (other ID, or a late reply to another read)
            dxl_id = self._ids[index]
            del pending[dxl_id]
            if error & ERROR_NUMBER_MASK:
                number = error & ERROR_NUMBER_MASK
                reason = (
                    f"sync-read reply carries error {number} "
                    f"({self._packet.getRxPacketError(number)})"
                )
                errors.append(f"{io.label(dxl_id)}: {reason}")
                reasons[dxl_id] = reason
            else:
                if self._direct is None:
                    raw[index] = self._decoder.unpack_from(bytes(packet), PKT_DATA)
                else:
                    raw[index, self._direct_columns] = self._decoder.unpack_from(
                        bytes(packet), PKT_DATA
                    )
                    raw[index, _HW_ERROR] = 0  # read below if the Alert bit says there is one
                valid[index] = True
                alert[index] = bool(error & ERRBIT_ALERT)
            if not pending:
                break
        if self._direct is not None:
            self._read_alerted_errors(raw, valid & alert, errors)
        if pending:
            why = f"{corrupt} corrupt reply(s) received" if corrupt else "timeout"
            for dxl_id in pending:
                reasons[dxl_id] = f"no valid sync-read reply ({why})"
                errors.append(f"{io.label(dxl_id)}: {reasons[dxl_id]}")
        return self._state_from_raw(raw, valid, alert, errors, reasons)

    def write_goals(self, goal_rad: np.ndarray) -> None:
        """One SYNC_WRITE of Goal Position for every joint (chain order, joint frame, rad).

        Raises ValueError BEFORE sending anything if a goal is not finite or outside its joint's
        [min_position_rad, max_position_rad]: a sync write has no reply, so the device's Data
        Limit error would be invisible. Goals inside the range map inside the device limits
        (they are rounded outwards, see `DynamixelJointConfig.device_position_limits_pulses`).
        """
        io = self._require_writable("goal positions")
        assert self._writes_goals
        goal = np.asarray(goal_rad, dtype=np.float64)
        if goal.shape != self._min_rad.shape:
            raise ValueError(
                f"write_goals needs one goal per joint, shape {self._min_rad.shape}, got shape "
                f"{goal.shape}"
            )
        inside = (goal >= self._min_rad) & (goal <= self._max_rad)  # False for NaN
        if np.count_nonzero(inside) != inside.size:
            out_of_range = ~inside
            details = "; ".join(
                f"{self._labels[self._ids[index]]}: goal {float(goal[index])} rad outside "
                f"[{float(self._min_rad[index])}, {float(self._max_rad[index])}]"
                for index in np.flatnonzero(out_of_range)
            )
            raise ValueError(f"goal position refused, nothing sent: {details}")
        pulses = rad_to_position(goal, self.units, self._direction, self._offset_rad)
        params = self._goal_params  # the goals as little-endian INT32s after each ID
        params[:, 1:] = pulses.astype("<i4").view(np.uint8).reshape(len(self._ids), 4)
        result = self._packet.syncWriteTxOnly(
            io.port, self._goal_address, 4, params.ravel().tolist(), params.size
        )
        if result != COMM_SUCCESS:
            raise BusError(
                f"sync write of Goal Position on {self.config.port} failed: "
                f"{self._packet.getTxRxResult(result)}"
            )

    # ------------------------------------------------------------------------- torque, reboot

    def enable(self, ids: Iterable[int] | None = None) -> None:
        """Torque on for the given Dynamixel IDs (all if None), without a jump.

        Checks first, for every target: Hardware Error Status must be 0 and the reply must not
        carry the Alert bit (else `DeviceShutdownError`: a REBOOT is needed), and Present
        Position must lie in the joint range. Then per device: Goal Position := Present
        Position, Torque Enable := 1, read back. If a later device fails, the earlier ones stay
        enabled (the caller decides; `disable()` is best effort).
        """
        io = self._require_writable("torque on")
        targets = self._select(ids)
        faulty = {}
        for dxl_id in targets:
            status = self.read_hardware_error(dxl_id)
            if status.bits or status.alert:
                faulty[dxl_id] = status.bits
        if faulty:
            details = "; ".join(
                f"{io.label(dxl_id)}: Hardware Error Status 0x{bits:02X} "
                f"({HardwareError.describe(bits)})"
                for dxl_id, bits in faulty.items()
            )
            raise DeviceShutdownError(
                f"cannot enable torque: {details}. The device is in shutdown (or has latched a "
                "hardware error); only a REBOOT clears it: remove the cause, then call "
                f"reboot({sorted(faulty)}).",
                hardware_errors=faulty,
            )
        present_item = self.spec.item("Present Position")
        present = {dxl_id: io.read_item(dxl_id, present_item) for dxl_id in targets}
        for dxl_id in targets:
            self._check_inside_limits(dxl_id, present[dxl_id])
        goal_item = self.spec.item("Goal Position")
        torque_item = self.spec.item("Torque Enable")
        for dxl_id in targets:
            io.write_item(dxl_id, goal_item, present[dxl_id])
            try:
                io.write_item(dxl_id, torque_item, 1)
            except DynamixelReplyError as exc:
                bits = self.read_hardware_error(dxl_id).bits
                raise DeviceShutdownError(
                    f"{io.label(dxl_id)} refused Torque Enable = 1 ({exc}); a device in "
                    f"shutdown needs a REBOOT: call reboot([{dxl_id}])",
                    hardware_errors={dxl_id: bits},
                ) from exc
            if io.read_item(dxl_id, torque_item) != 1:
                bits = self.read_hardware_error(dxl_id).bits
                raise DeviceShutdownError(
                    f"{io.label(dxl_id)}: Torque Enable reads 0 after writing 1 (Hardware "
                    f"Error Status 0x{bits:02X}: {HardwareError.describe(bits)}); a device in "
                    f"shutdown needs a REBOOT: call reboot([{dxl_id}])",
                    hardware_errors={dxl_id: bits},
                )

    def disable(self, ids: Iterable[int] | None = None) -> None:
        """Torque off on every given device (all if None), best effort.

        Every device is tried even if one fails; afterwards one `BusError` lists the failures.
        A reply with only the Alert bit set counts as success (a device in shutdown).
        If the port itself has failed (or fails now), `PortGoneError` says so, names the devices
        whose torque could not be turned off and whether the command reached any of them:
        nothing is claimed that did not happen on the wire.
        """
        io = self._require_writable("torque off")
        targets = self._select(ids)
        if io.port.failure is not None:
            raise self._torque_off_lost(io, io.port.gone_error("write"), [], targets)
        failures = []
        confirmed: list[int] = []
        torque_item = self.spec.item("Torque Enable")
        for position, dxl_id in enumerate(targets):
            try:
                io.write_item(dxl_id, torque_item, 0)
                if io.read_item(dxl_id, torque_item) != 0:
                    failures.append(f"{io.label(dxl_id)}: Torque Enable still reads 1")
                else:
                    confirmed.append(dxl_id)
            except PortGoneError as exc:
                raise self._torque_off_lost(io, exc, confirmed, targets[position:]) from exc
            except BusError as exc:
                failures.append(str(exc))
        if failures:
            raise BusError("disable() could not turn torque off everywhere: " + "; ".join(failures))

    def _torque_off_lost(
        self,
        io: DeviceIO,
        error: PortGoneError,
        confirmed: list[int],
        lost: tuple[int, ...],
    ) -> PortGoneError:
        """The error of a disable() that the port's failure cut short (see disable)."""
        first, rest = lost[0], lost[1:]
        if error.packet_was_sent:
            in_flight = (
                f"Torque Enable = 0 was sent to {io.label(first)} but the port failed before "
                "its reply: its torque state is unknown"
            )
        else:
            in_flight = f"no Torque Enable = 0 reached {io.label(first)}"
        parts = [
            f"disable(): the Dynamixel port {error.port} is gone ({error.reason}); torque "
            f"could not be turned off: {in_flight}"
        ]
        if rest:
            parts.append("nothing was sent to " + ", ".join(io.label(dxl_id) for dxl_id in rest))
        if confirmed:
            parts.append(
                "torque off was confirmed on " + ", ".join(io.label(dxl_id) for dxl_id in confirmed)
            )
        parts.append(
            "devices that had torque on keep it until their power is cut or the port is back"
        )
        return PortGoneError(
            "; ".join(parts) + ".", port=error.port, reason=error.reason, operation=error.operation
        )

    def reboot(self, ids: Iterable[int] | None = None) -> dict[int, HardwareErrorStatus]:
        """REBOOT the given devices (all if None); returns their hardware error status after.

        Sends REBOOT (0x08) to each, then PINGs until every one answers again, bounded by
        `reboot_timeout_s` (else `BusError`); then re-applies the RAM settings (Status Return
        Level, gains). Torque is off after a reboot (RAM defaults): call `enable()` to resume.
        """
        io = self._require_writable("reboot")
        targets = self._select(ids)
        for dxl_id in targets:
            result, error = self._packet.reboot(io.port, dxl_id)
            io.check(dxl_id, "REBOOT", result, error)
        deadline = time.perf_counter() + self.config.reboot_timeout_s
        pending = list(targets)
        while True:
            pending = [dxl_id for dxl_id in pending if io.ping(dxl_id)[1] != COMM_SUCCESS]
            if not pending:
                break
            if time.perf_counter() > deadline:
                raise BusError(
                    f"after REBOOT, {', '.join(io.label(i) for i in pending)} did not answer "
                    f"PING within reboot_timeout_s={self.config.reboot_timeout_s} s on {io.where}"
                )
            time.sleep(REBOOT_POLL_INTERVAL_S)
        for dxl_id in targets:
            configure.apply_ram_settings(io, self._joints[self._index_of[dxl_id]], self.spec)
        return {dxl_id: self.read_hardware_error(dxl_id) for dxl_id in targets}

    def read_hardware_error(self, dxl_id: int) -> HardwareErrorStatus:
        """A single READ of Hardware Error Status (892), with the Alert bit of that reply."""
        io = self._settle()
        self._select([dxl_id])
        item = self.spec.item("Hardware Error Status")
        data, alert = io.read_bytes_with_alert(dxl_id, item.address, item.size, f"read {item.name}")
        return HardwareErrorStatus(dxl_id, data[0], alert)

    # ------------------------------------------------------------------------------ internals

    def _read_alerted_errors(self, raw: np.ndarray, alerted: np.ndarray, errors: list[str]) -> None:
        """Span reads only: Hardware Error Status of each device whose reply carried the Alert
        bit (one READ each; none while every device is healthy)."""
        io = self._require_io()
        for index in np.flatnonzero(alerted):
            dxl_id = self._ids[index]
            try:
                raw[index, _HW_ERROR] = self.read_hardware_error(dxl_id).bits
            except BusError as exc:
                errors.append(f"{io.label(dxl_id)}: Alert set, Hardware Error Status unread: {exc}")

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

    def _check_inside_limits(self, dxl_id: int, present_pulses: int) -> None:
        low, high = self._device_limits[dxl_id]
        if low <= present_pulses <= high:
            return
        index = self._index_of[dxl_id]
        angle = float(
            position_to_rad(
                present_pulses, self.units, self._direction[index], self._offset_rad[index]
            )
        )
        raise BusError(
            f"cannot enable torque on {self._labels[dxl_id]}: its position {angle:.4f} rad is "
            f"outside the joint range [{float(self._min_rad[index])}, "
            f"{float(self._max_rad[index])}] rad; "
            "move it inside by hand (torque off) or widen the range in the configuration"
        )

    def _state_from_raw(
        self,
        raw: np.ndarray,
        valid: np.ndarray,
        alert: np.ndarray,
        errors: list[str],
        reasons: dict[int, str],
    ) -> DynamixelState:
        units, direction = self.units, self._direction
        position_rad = position_to_rad(raw[:, _POSITION], units, direction, self._offset_rad)
        velocity_rad_s = velocity_to_rad_s(raw[:, _VELOCITY], units, direction)
        current_a = current_to_a(raw[:, _CURRENT], units, direction)
        voltage_v = input_voltage_to_v(raw[:, _VOLTAGE])
        temperature_c = raw[:, _TEMPERATURE].astype(np.float64)
        hardware_error = raw[:, _HW_ERROR]
        torque_enabled = raw[:, _TORQUE] != 0
        if np.count_nonzero(valid) != valid.size:  # an entry not read is NaN (0, off)
            invalid = ~valid
            for values in (position_rad, velocity_rad_s, current_a, voltage_v, temperature_c):
                values[invalid] = np.nan
            hardware_error = np.where(valid, hardware_error, 0)
            torque_enabled &= valid
        return DynamixelState(
            dxl_ids=self._ids,
            position_rad=position_rad,
            velocity_rad_s=velocity_rad_s,
            current_a=current_a,
            torque_estimate_nm=current_a_to_torque_estimate_nm(current_a, units),
            input_voltage_v=voltage_v,
            temperature_c=temperature_c,
            hardware_error=hardware_error.astype(np.uint8),
            torque_enabled=torque_enabled,
            alert=alert,
            valid=valid,
            errors=errors,
            invalid_reasons=reasons,
        )

    def _open_devices(self, io: DeviceIO, allow_torque_off: bool) -> None:
        found = configure.identify(io, self._ids, self.spec)
        if not self.read_only:
            for dxl_id in self._ids:
                configure.ensure_status_return_level(io, dxl_id, self.spec)
        plans = {
            joint.dxl_id: configure.eeprom_plan(io, joint, self.config, self.layout)
            for joint in self._joints
        }
        torque_item = self.spec.item("Torque Enable")
        torque_on = {dxl_id: io.read_item(dxl_id, torque_item) != 0 for dxl_id in self._ids}
        if self.read_only:
            map_start = self.layout.indirect_address_start
            unmapped = any(w.address == map_start for plan in plans.values() for w in plan)
            if unmapped:  # the map is an EEPROM write: read the plain span instead
                self._direct = DirectStateSpan(self.spec)
                self._decoder = self._direct.decoder()
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
        torque_item = self.spec.item("Torque Enable")
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
                io.write_item(dxl_id, torque_item, 0)
                torque_on[dxl_id] = io.read_item(dxl_id, torque_item) != 0
            configure.apply_eeprom_plan(io, dxl_id, plans[dxl_id])
        for joint in self._joints:
            configure.apply_ram_settings(io, joint, self.spec)

    def _finish_open(
        self,
        io: DeviceIO,
        found: dict[int, tuple[int, int]],
        plans: dict[int, list[configure.EepromWrite]],
        torque_on: dict[int, bool],
    ) -> None:
        shutdown_item = self.spec.item("Shutdown")
        torque_limit_item = self.spec.item("Torque Limit")
        self.devices = tuple(
            DeviceInfo(
                dxl_id=dxl_id,
                model_number=found[dxl_id][0],
                firmware_version=found[dxl_id][1],
                shutdown_mask=io.read_item(dxl_id, shutdown_item),
                hardware_error=self.read_hardware_error(dxl_id).bits,
                torque_enabled=torque_on[dxl_id],
                eeprom_changes=tuple(write.description for write in plans[dxl_id]),
                current_limit_a=current_limit_raw_to_a(
                    io.read_item(dxl_id, torque_limit_item), self.spec.units
                ),
            )
            for dxl_id in self._ids
        )
        block = self.layout if self._direct is None else self._direct
        self._sync_read = GroupSyncRead(io.port, self._packet, block.data_start, block.size)
        self._writes_goals = True
        for dxl_id in self._ids:
            self._sync_read.addParam(dxl_id)
