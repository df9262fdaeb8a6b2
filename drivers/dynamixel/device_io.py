"""Checked single-device transactions over the SDK: every failure becomes a clear `BusError`.

Used for everything outside the 200 Hz path (identification, configuration, enable, reboot).
The Alert bit (0x80) alone is not a failure: a status packet carrying it still holds valid data
(e-Manual Protocol 2.0; the SDK returns COMM_SUCCESS with the bit set in `error`).

READ and PING replies are checked for their length: the SDK's `readRx` and `ping` take the
requested number of bytes from the buffer whatever the status packet's LEN says, so a shorter
(CRC-good) reply handed back its own CRC bytes as data (found by fuzzing the receive path).
Both are therefore done here with the SDK's public `readTx`/`txRxPacket` and `rxPacket`.
"""

from __future__ import annotations

from collections.abc import Mapping

from dynamixel_sdk import COMM_RX_CORRUPT, COMM_SUCCESS, PacketHandler

from drivers.dynamixel.control_table import ControlItem
from drivers.dynamixel.errors import DynamixelReplyError
from drivers.dynamixel.port import LowLatencyPortHandler
from drivers.joint_bus import BusError

ERRBIT_ALERT = 0x80  # Protocol 2.0 status ERR byte, bit 7
ERROR_NUMBER_MASK = 0x7F  # bits 6..0: the error number

# Status packet after the SDK removed the stuffing (e-Manual Protocol 2.0, "Status Packet"):
# FF FF FD 00 | ID | LEN_L LEN_H | 0x55 | ERR | params... | CRC_L CRC_H; LEN = params + 4.
PKT_ID, PKT_LENGTH_L, PKT_LENGTH_H, PKT_ERROR, PKT_PARAMS = 4, 5, 6, 8, 9
STATUS_LENGTH_OVERHEAD = 4  # INST + ERR + CRC(2)
INST_PING = 0x01
PING_PARAMS = 3  # model number (2), firmware version (1)


class DeviceIO:
    """Reads and writes of one item or byte range on one device, checked.

    labels: {dxl_id: "ID 3 (knee)"} for messages; where: "port at baud" for messages.
    """

    def __init__(
        self,
        port: LowLatencyPortHandler,
        packet: PacketHandler,
        *,
        labels: Mapping[int, str],
        where: str,
    ) -> None:
        self.port = port
        self.packet = packet
        self._labels = labels
        self.where = where

    def label(self, dxl_id: int) -> str:
        return self._labels.get(dxl_id, f"ID {dxl_id}")

    def check(self, dxl_id: int, what: str, result: int, error: int) -> None:
        """Raise for a failed transaction or an error number; the Alert bit alone is fine."""
        if result != COMM_SUCCESS:
            raise BusError(
                f"{self.label(dxl_id)}: {what} failed on {self.where}: "
                f"{self.packet.getTxRxResult(result)}"
            )
        error_number = error & ERROR_NUMBER_MASK
        if error_number:
            alert = bool(error & ERRBIT_ALERT)
            raise DynamixelReplyError(
                f"{self.label(dxl_id)}: {what} answered with error {error_number} "
                f"({self.packet.getRxPacketError(error_number)})"
                + (" and the Alert bit (hardware error)" if alert else ""),
                dxl_id=dxl_id,
                error_number=error_number,
                alert=alert,
            )

    def read_bytes_with_alert(
        self, dxl_id: int, address: int, length: int, what: str
    ) -> tuple[bytes, bool]:
        """READ `length` bytes at `address`; returns (data, Alert bit of the reply)."""
        self.check(dxl_id, what, self.packet.readTx(self.port, dxl_id, address, length), 0)
        while True:  # the SDK's readRx: skip status packets of other IDs
            status, result = self.packet.rxPacket(self.port, False)
            self.check(dxl_id, what, result, 0)
            if status[PKT_ID] == dxl_id:
                break
        error = status[PKT_ERROR]
        self.check(dxl_id, what, result, error)
        carried = _status_params(status)
        if carried != length:
            raise BusError(
                f"{self.label(dxl_id)}: {what} answered with {carried} data bytes, expected "
                f"{length}"
            )
        return bytes(status[PKT_PARAMS : PKT_PARAMS + length]), bool(error & ERRBIT_ALERT)

    def read_bytes(self, dxl_id: int, address: int, length: int, what: str) -> bytes:
        return self.read_bytes_with_alert(dxl_id, address, length, what)[0]

    def write_bytes(self, dxl_id: int, address: int, data: bytes, what: str) -> None:
        result, error = self.packet.writeTxRx(self.port, dxl_id, address, len(data), list(data))
        self.check(dxl_id, what, result, error)

    def read_item(self, dxl_id: int, item: ControlItem) -> int:
        data = self.read_bytes(dxl_id, item.address, item.size, f"read {item.name}")
        return int.from_bytes(data, "little", signed=item.signed)

    def write_item(self, dxl_id: int, item: ControlItem, value: int) -> None:
        self.write_bytes(dxl_id, item.address, encode(item, value), f"write {item.name} = {value}")

    def ping(self, dxl_id: int) -> tuple[int, int]:
        """(model number, SDK result code) of a PING; the result is not checked. A reply
        without the three PING parameters counts as corrupt (COMM_RX_CORRUPT)."""
        request = [0] * 10
        request[PKT_ID] = dxl_id
        request[PKT_LENGTH_L] = 3
        request[7] = INST_PING
        status, result, _ = self.packet.txRxPacket(self.port, request)
        if result != COMM_SUCCESS:
            return 0, result
        if _status_params(status) != PING_PARAMS:
            return 0, COMM_RX_CORRUPT
        return status[PKT_PARAMS] | (status[PKT_PARAMS + 1] << 8), result


def encode(item: ControlItem, value: int) -> bytes:
    """The item's bytes for `value` (little endian), or ValueError if it cannot hold it."""
    if not item.writable:
        raise ValueError(f"{item.name} ({item.address}) is read-only")
    try:
        return value.to_bytes(item.size, "little", signed=item.signed)
    except OverflowError:
        raise ValueError(
            f"{value} does not fit {item.name} ({item.size} bytes, "
            f"{'signed' if item.signed else 'unsigned'})"
        ) from None


def _status_params(status: list[int]) -> int:
    """How many parameter bytes a status packet carries (its LEN field less INST/ERR/CRC)."""
    return (status[PKT_LENGTH_L] | (status[PKT_LENGTH_H] << 8)) - STATUS_LENGTH_OVERHEAD
