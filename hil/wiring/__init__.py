"""Building the bus a run talks to: for the hardware, for an emulator, or in-process.

connection.py   where the buses are (ports of the configuration, of an emulator, overrides)
hardware.py     the drivers' configuration from the file; device checks; `make_bus`
emulation.py    the emulator's spec from the file and an experiment; the emulator process
in_process.py   a JointBus on the emulated plant in this process (fast loop tests)
process_activity.py  what a process of the run is doing (/proc): what lock-step waits go on by
"""

from hil.wiring.checks import check_devices
from hil.wiring.connection import Connection, SerialEndpoint
from hil.wiring.hardware import (
    bus_config,
    configured_current_limits_a,
    encoder_counts_per_rev,
    make_bus,
)

__all__ = [
    "Connection",
    "SerialEndpoint",
    "bus_config",
    "check_devices",
    "configured_current_limits_a",
    "encoder_counts_per_rev",
    "make_bus",
]
