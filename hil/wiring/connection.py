"""Where the buses are: the ports of the configuration, of a running emulator, or overridden.

A `Connection` names, per Dynamixel chain, its serial port and baud rate, and per CAN channel
the `can.Bus(...)` keyword arguments - after every override, so that a run records what it
actually drove (`record`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from hil.config import Config, ConfigError


@dataclass(frozen=True)
class SerialEndpoint:
    port: str
    baudrate: int


@dataclass(frozen=True)
class Connection:
    """Ports by chain name and CAN keyword arguments by channel name; for an emulator, whether
    it is in lock-step and its process (`emulator_pid`: the "pid" of its endpoints, which an
    embedded emulator's have), which a lock-step bus waits for while it works."""

    dynamixel: dict[str, SerialEndpoint]
    can: dict[str, dict[str, Any]]
    lockstep: bool = False
    emulated: bool = False
    emulator_pid: int | None = None

    @classmethod
    def from_config(cls, config: Config, *, require_ports: bool = True) -> Connection:
        if require_ports:
            for section in config.dynamixel:
                if not section.port:
                    raise ConfigError(
                        f"{config.source} [[dynamixel]] {section.name!r} port: missing (the "
                        "serial port of the RS-485 adapter, e.g. /dev/ttyUSB0)"
                    )
        return cls(
            {d.name: SerialEndpoint(d.port, d.baudrate) for d in config.dynamixel},
            {c.name: c.bus_kwargs() for c in config.can},
        )

    @classmethod
    def from_endpoints(cls, endpoints: dict[str, Any], config: Config) -> Connection:
        """The buses a `hil emulate` serves (its first stdout line), for this configuration's
        chains, in order, and channel (an emulator serves one CAN channel)."""
        if len(config.can) != 1:
            raise ConfigError(
                f"{config.source}: the emulator serves one CAN channel; this configuration "
                f"has {len(config.can)}"
            )
        try:
            ports = [
                str(p) for p in endpoints.get("dynamixel_ports") or [endpoints["dynamixel_port"]]
            ]
            bauds = [int(b) for b in endpoints.get("baudrates") or [endpoints["baudrate"]]]
            can_kwargs = dict(endpoints["can"])
            pid = endpoints.get("pid")
            pid = None if pid is None else int(pid)
        except (KeyError, TypeError, ValueError) as exc:
            raise ConfigError(f"the emulator's endpoints lack or garble {exc}") from None
        if len(ports) != len(config.dynamixel) or len(bauds) != len(ports):
            raise ConfigError(
                f"{config.source}: the emulator serves {len(ports)} Dynamixel chain(s); this "
                f"configuration has {len(config.dynamixel)} ([[dynamixel]])"
            )
        return cls(
            {
                section.name: SerialEndpoint(port, baudrate)
                for section, port, baudrate in zip(config.dynamixel, ports, bauds, strict=True)
            },
            {config.can[0].name: can_kwargs},
            lockstep=endpoints.get("clock") == "lockstep",
            emulated=True,
            emulator_pid=pid,
        )

    def with_overrides(
        self,
        port: str | None = None,
        baudrate: int | None = None,
        can_interface: str | None = None,
        can_channel: str | None = None,
    ) -> Connection:
        """--port/--baudrate and --can-interface/--can-channel: for a robot with one chain and
        one CAN channel (with several, edit the configuration file)."""
        dynamixel, can = dict(self.dynamixel), {k: dict(v) for k, v in self.can.items()}
        if port or baudrate:
            chain = _only(dynamixel, "--port/--baudrate", "Dynamixel chains")
            old = dynamixel[chain]
            dynamixel[chain] = SerialEndpoint(port or old.port, baudrate or old.baudrate)
        if can_interface or can_channel:
            name = _only(can, "--can-interface/--can-channel", "CAN channels")
            kwargs = can[name]
            if can_interface:
                kwargs["interface"] = can_interface
                if can_interface == "slcan":
                    kwargs.setdefault("sleep_after_open", 0)
            if can_channel:
                kwargs["channel"] = can_channel
        return dataclasses.replace(self, dynamixel=dynamixel, can=can)

    def record(self) -> dict[str, Any]:
        """What a run drives, as plain data."""
        return {
            "dynamixel": {
                name: {"port": e.port, "baudrate": e.baudrate} for name, e in self.dynamixel.items()
            },
            "can": {
                name: {k: v for k, v in kwargs.items() if k in ("interface", "channel", "bitrate")}
                for name, kwargs in self.can.items()
            },
            "emulated": self.emulated,
            "lockstep": self.lockstep,
        }

    def describe(self) -> str:
        """'/dev/ttyUSB0 @ 3000000 bps, socketcan:can0' for the banner."""
        ports = ", ".join(f"{e.port} @ {e.baudrate} bps" for e in self.dynamixel.values())
        channels = ", ".join(f"{k.get('interface')}:{k.get('channel')}" for k in self.can.values())
        return f"{ports}; {channels}"


def _only(table: dict[str, Any], option: str, what: str) -> str:
    if len(table) != 1:
        raise ConfigError(
            f"{option} points one bus elsewhere, but the configuration has {len(table)} {what} "
            f"({sorted(table)}): set their ports in the configuration file"
        )
    return next(iter(table))
