"""Everything a configuration's devices must satisfy, checked before anything is opened."""

from __future__ import annotations

from hil.config import Config, ConfigError
from hil.wiring.connection import Connection
from hil.wiring.emulation import plant_servo_noise
from hil.wiring.hardware import bus_config


def check_devices(config: Config) -> None:
    """Every device figure the drivers check, and the [emulator] section, checked now (no port
    is opened), whatever the run will drive: ConfigError naming the file and the device."""
    try:
        bus_config(config, Connection.from_config(config, require_ports=False))
    except ValueError as exc:
        raise ConfigError(f"{config.source}: {exc}") from exc
    plant_servo_noise(config)
