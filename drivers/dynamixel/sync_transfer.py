"""The 200 Hz path of a `DynamixelChain`: one SYNC_READ of the state block in, one SYNC_WRITE of
Goal Position (4 bytes) out, and the state block decoded into SI units, each device in its own
model's units (a chain that mixes layouts: one transaction per group, `transfer_groups.py`).

Protocol facts (ROBOTIS e-Manual, Protocol 2.0 and the models' pages):
- A SYNC_WRITE gets no reply: a goal outside Min/Max Position Limit (40/36) would be dropped
  with a Data Limit error nobody sees, so goals are checked here before sending.
- In a SYNC_READ the devices answer in the order listed; if one stays silent the ones after it
  do not answer either (ROBOTIS maintainer, DynamixelSDK issue #364).

Reading the sync-read replies: the SDK's `GroupSyncRead.rxPacket()` drops each device's ERR byte
and, if any device fails, makes `getData` return 0 for all of them; its `readRx()` discards a
reply whose ID it does not expect next. `read_state()` therefore sends with
`GroupSyncRead.txPacket()` and collects the status packets with the SDK's public
`PacketHandler.rxPacket()` (framing, CRC check, unstuffing) under the single timeout
`syncReadTx` set for the group, matching them by ID: each device keeps its own validity and its
Alert bit, and a lost reply costs only that device. The SDK is used unmodified.
"""

from __future__ import annotations

import numpy as np
from dynamixel_sdk import COMM_RX_TIMEOUT, COMM_SUCCESS

from drivers.dynamixel.device_io import ERRBIT_ALERT, ERROR_NUMBER_MASK, DeviceIO
from drivers.dynamixel.state import DynamixelState
from drivers.dynamixel.state_block import STATE_BLOCK_ITEMS
from drivers.dynamixel.transfer_groups import ReadGroup
from drivers.dynamixel.units import (
    current_a_to_torque_estimate_nm,
    current_to_a,
    input_voltage_to_v,
    position_to_rad,
    rad_to_position,
    velocity_to_rad_s,
)
from drivers.joint_bus import BusError

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


class SyncTransfer:
    """The per-tick transactions of `DynamixelChain` (drivers/dynamixel/chain.py), a mixin: they
    work on the chain's port, decoder and preallocated buffers."""

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
        """Send the (first) SYNC_READ and return at once: the replies travel (wire time, Return
        Delay Time, the adapter's latency timer) while the caller does other work;
        `receive_state()` collects them. The reply timeout runs from here. (A chain that needs
        more than one sync read, `transfer_groups.py`, sends the others in `receive_state`.)"""
        self._settle()
        sync_read = self._read_groups[0].sync_read
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
        for number, group in enumerate(self._read_groups):
            if number:
                assert group.sync_read is not None
                result = group.sync_read.txPacket()
            self._collect(io, group, result, raw, valid, alert, errors, reasons)
        return self._state_from_raw(raw, valid, alert, errors, reasons)

    def _collect(
        self,
        io: DeviceIO,
        group: ReadGroup,
        result: int,
        raw: np.ndarray,
        valid: np.ndarray,
        alert: np.ndarray,
        errors: list[str],
        reasons: dict[int, str],
    ) -> None:
        """One sync read's replies into the state arrays (see the module docstring)."""
        if result != COMM_SUCCESS:
            reason = f"sync read not sent: {self._packet.getTxRxResult(result)}"
            errors.append(reason)
            reasons.update(dict.fromkeys(group.ids, reason))
            return
        expected_length = group.expected_length
        decoder, columns = group.decoder, group.columns
        pending = {dxl_id: self._index_of[dxl_id] for dxl_id in group.ids}
        corrupt = 0
        # Replies are matched by ID, so one lost or corrupted reply does not also cost the
        # (valid) replies after it. Each rxPacket call either consumes bytes or reports the
        # group's timeout, so the loop ends; the bound guards against a babbling line.
        for _ in range(2 * len(group.ids) + 2):
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
                if columns is None:
                    raw[index] = decoder.unpack_from(bytes(packet), PKT_DATA)
                else:
                    raw[index, columns] = decoder.unpack_from(bytes(packet), PKT_DATA)
                    if not group.reads_hardware_error:
                        raw[index, _HW_ERROR] = 0  # read below if the Alert bit says there is one
                valid[index] = True
                alert[index] = bool(error & ERRBIT_ALERT)
            if not pending:
                break
        if not group.reads_hardware_error:
            self._read_alerted_errors(raw, group.indices, valid & alert, errors)
        if pending:
            why = f"{corrupt} corrupt reply(s) received" if corrupt else "timeout"
            for dxl_id in pending:
                reasons[dxl_id] = f"no valid sync-read reply ({why})"
                errors.append(f"{io.label(dxl_id)}: {reasons[dxl_id]}")

    def write_goals(self, goal_rad: np.ndarray) -> None:
        """One SYNC_WRITE of Goal Position for every joint (chain order, joint frame, rad); one
        per Goal Position address on a chain that mixes the PRO and PRO+ layouts.

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
        wire = pulses.astype("<i4").view(np.uint8).reshape(len(self._ids), 4)
        for group in self._write_groups:
            params = group.params  # the goals as little-endian INT32s after each ID
            params[:, 1:] = wire if len(self._write_groups) == 1 else wire[group.indices]
            result = self._packet.syncWriteTxOnly(
                io.port, group.address, 4, params.ravel().tolist(), params.size
            )
            if result != COMM_SUCCESS:
                raise BusError(
                    f"sync write of Goal Position on {self.config.port} failed: "
                    f"{self._packet.getTxRxResult(result)}"
                )

    def _read_alerted_errors(
        self, raw: np.ndarray, indices: np.ndarray, alerted: np.ndarray, errors: list[str]
    ) -> None:
        """Span reads without Hardware Error Status only: that item of each device of the group
        (`indices`) whose reply carried the Alert bit (one READ each; none while all are
        healthy)."""
        io = self._require_io()
        for index in indices[alerted[indices]]:
            dxl_id = self._ids[index]
            try:
                raw[index, _HW_ERROR] = self.read_hardware_error(dxl_id).bits
            except BusError as exc:
                errors.append(f"{io.label(dxl_id)}: Alert set, Hardware Error Status unread: {exc}")

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
