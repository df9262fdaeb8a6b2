"""Everything a configuration's devices must satisfy, checked before anything is opened."""

from __future__ import annotations

import math

from hil.config import Config, ConfigError
from hil.robots import profile_of
from hil.wiring.connection import Connection
from hil.wiring.emulation import plant_servo_noise
from hil.wiring.hardware import bus_config, encoder_counts_per_rev

# A CiA 406 position value is an INTEGER32 count (0x6004): no reading lies outside +-2**31.
INT32_COUNTS = 2**31


def check_devices(config: Config) -> None:
    """Every device figure the drivers check, the link encoders' offsets, the robot description
    and the [emulator] section, checked now (no port is opened), whatever the run will drive:
    ConfigError naming the file and the device or key."""
    try:
        bus_config(config, Connection.from_config(config, require_ports=False))
    except ValueError as exc:
        raise ConfigError(f"{config.source}: {exc}") from exc
    _check_encoder_offsets(config)
    profile_of(config).check(config)  # the robot's own (a URDF its model builds from, ...)
    plant_servo_noise(config)


def _check_encoder_offsets(config: Config) -> None:
    """An encoder offset is a reading of the encoder (at the link's zero): one its INTEGER32
    count cannot hold would refuse every run at its start gate, after the bus was opened."""
    for number, joint in enumerate(config.joints, start=1):
        per_rev = encoder_counts_per_rev(joint)
        reach_rad = 2.0 * math.pi * INT32_COUNTS / per_rev
        if abs(joint.encoder_offset_rad) > reach_rad:
            raise ConfigError(
                f"{config.source} [[joint]] #{number} {joint.name!r} encoder_offset_rad: "
                f"{joint.encoder_offset_rad!r} rad is no reading of its encoder (an INTEGER32 "
                f"count at {per_rev} counts/rev reaches +-{reach_rad:.0f} rad)"
            )
