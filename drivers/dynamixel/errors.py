"""Errors of the Dynamixel driver; all are `BusError`s, so the loop can catch one type."""

from __future__ import annotations

from drivers.joint_bus import BusError


class DynamixelReplyError(BusError):
    """A device answered, but its status packet carried an error number (Protocol 2.0 ERR byte).

    error_number: bits 6..0 of the ERR byte (1 Result Fail, 2 Instruction, 3 CRC, 4 Data Range,
        5 Data Length, 6 Data Limit, 7 Access; e-Manual Protocol 2.0, "Status Packet").
    alert: bit 7 of the ERR byte (the device has a hardware error; read item 892).
    """

    def __init__(self, message: str, *, dxl_id: int, error_number: int, alert: bool) -> None:
        super().__init__(message)
        self.dxl_id = dxl_id
        self.error_number = error_number
        self.alert = alert


class DeviceShutdownError(BusError):
    """A device reports a hardware error (it is, or may be, in shutdown): only a REBOOT clears it.

    hardware_errors: {dxl_id: Hardware Error Status bits} of the devices concerned.
    """

    def __init__(self, message: str, *, hardware_errors: dict[int, int]) -> None:
        super().__init__(message)
        self.hardware_errors = hardware_errors


class EepromChangeRefused(BusError):
    """open() needs to change EEPROM items of a device whose torque is on, and was not allowed to
    turn torque off (the link would fall)."""


class PortGoneError(BusError):
    """The serial port itself failed (the adapter was unplugged or lost power, the emulator
    stopped): nothing can be sent or received on it any more.

    port: the port's path. reason: the operating system's error. operation: the port operation
    that failed ("clear", "write", "read", "bytes available"); a "clear" or "write" failure
    means the packet in hand did not reach the wire.
    """

    def __init__(self, message: str, *, port: str, reason: str, operation: str) -> None:
        super().__init__(message)
        self.port = port
        self.reason = reason
        self.operation = operation

    @property
    def packet_was_sent(self) -> bool:
        """Whether the packet being exchanged when the port failed had been written."""
        return self.operation not in ("clear", "write")
