"""Opening python-can's slcan interface on a read-ahead serial port.

`slcan_read_ahead(bus_kwargs)` rewrites an slcan channel `PORT[@BAUD]` to
`readahead://PORT[@BAUD]`, a pyserial URL whose handler (drivers/canbus/pyserial_handlers/
protocol_readahead.py) reads everything waiting in one system call where python-can asks for
one byte at a time. python-can and pyserial are used unmodified: pyserial looks URL handlers up
in `serial.protocol_handler_packages`, to which `register()` adds ours.
"""

from __future__ import annotations

from typing import Any

import serial

from drivers.canbus.pyserial_handlers.protocol_readahead import SCHEME
from drivers.canbus.pyserial_handlers.protocol_readahead import Serial as ReadAheadSerial

HANDLER_PACKAGE = "drivers.canbus.pyserial_handlers"

__all__ = ["ReadAheadSerial", "register", "slcan_read_ahead"]


def register() -> None:
    """Let `serial.serial_for_url` open `readahead://` URLs (idempotent)."""
    if HANDLER_PACKAGE not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(HANDLER_PACKAGE)


def slcan_read_ahead(bus_kwargs: dict[str, Any]) -> dict[str, Any]:
    """The keyword arguments with an slcan channel on the read-ahead port; others unchanged
    (another interface, or a channel that already names a pyserial URL)."""
    channel = bus_kwargs.get("channel")
    if bus_kwargs.get("interface") != "slcan" or not isinstance(channel, str):
        return bus_kwargs
    if "://" in channel or not channel:
        return bus_kwargs
    register()
    return {**bus_kwargs, "channel": f"{SCHEME}://{channel}"}
