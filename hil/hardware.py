"""From the configuration file to the drivers: the JointBus a run talks to.

The same function builds the bus for the real testbed and for an emulated one; only the ports
differ (`Connection`). In lock-step emulation the timeouts are widened: the emulator answers
every request, but a loaded machine may delay it by tens of milliseconds, and a timeout that
fired on such a delay would make the run depend on the machine's load.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from drivers.canbus import ForceSensorConfig, LinkEncoderConfig
from drivers.dynamixel import DynamixelChainConfig, DynamixelJointConfig
from drivers.dynamixel_can_bus import DynamixelCanBus, DynamixelCanBusConfig
from hil.config import Config, ConfigError

LOCKSTEP_LATENCY_TIMER_MS = 50.0
LOCKSTEP_LINK_TIMEOUT_S = 0.2
# An emulator on a shared 2-core machine answers a fresh request 3-7 ms late now and then (a
# process scheduling artefact, not a property of the bus): with the hardware's 1 ms latency
# setting (~4 ms reply timeout) such replies would count as lost. Real-time emulation keeps the
# wire timing and widens only this allowance.
EMULATED_LATENCY_TIMER_MS = 10.0


@dataclass(frozen=True)
class Connection:
    """Where the buses are: from the configuration, or from a running emulator's endpoints."""

    port: str
    baudrate: int
    can_bus_kwargs: dict[str, Any]
    lockstep: bool = False
    emulated: bool = False

    @classmethod
    def from_config(cls, config: Config) -> Connection:
        if not config.dynamixel.port:
            raise ConfigError(f"{config.source} [dynamixel] port: missing")
        return cls(config.dynamixel.port, config.dynamixel.baudrate, config.can.bus_kwargs())

    @classmethod
    def from_endpoints(cls, endpoints: dict[str, Any]) -> Connection:
        return cls(
            port=endpoints["dynamixel_port"],
            baudrate=int(endpoints["baudrate"]),
            can_bus_kwargs=dict(endpoints["can"]),
            lockstep=endpoints.get("clock") == "lockstep",
            emulated=True,
        )

    def with_overrides(
        self,
        port: str | None = None,
        baudrate: int | None = None,
        can_interface: str | None = None,
        can_channel: str | None = None,
    ) -> Connection:
        kwargs = dict(self.can_bus_kwargs)
        if can_interface:
            kwargs["interface"] = can_interface
            if can_interface == "slcan":
                kwargs.setdefault("sleep_after_open", 0)
        if can_channel:
            kwargs["channel"] = can_channel
        return dataclasses.replace(
            self,
            port=port or self.port,
            baudrate=baudrate or self.baudrate,
            can_bus_kwargs=kwargs,
        )


def bus_config(config: Config, connection: Connection) -> DynamixelCanBusConfig:
    dxl = config.dynamixel
    lockstep = connection.lockstep
    chain = DynamixelChainConfig(
        port=connection.port,
        baudrate=connection.baudrate,
        joints=tuple(
            DynamixelJointConfig(
                dxl_id=j.dynamixel_id,
                direction=j.motor_direction,
                offset_rad=j.motor_offset_rad,
                min_position_rad=j.min_angle_rad,
                max_position_rad=j.max_angle_rad,
                torque_limit_a=j.torque_limit_a,
                name=j.name,
            )
            for j in config.joints
        ),
        return_delay_time_us=dxl.return_delay_time_us,
        latency_timer_ms=(
            LOCKSTEP_LATENCY_TIMER_MS
            if lockstep
            else EMULATED_LATENCY_TIMER_MS
            if connection.emulated
            else dxl.latency_timer_ms
        ),
    )
    period = config.loop.period_s
    encoders = tuple(
        LinkEncoderConfig(
            node_id=j.encoder_node_id,
            counts_per_rev=j.encoder_counts_per_rev,
            offset_rad=j.encoder_offset_rad,
            direction=j.encoder_direction,
            stale_after_s=config.safety.link_stale_ticks * period,
        )
        for j in config.joints
    )
    force = None
    if config.force_sensor.node_id:
        force = ForceSensorConfig(
            node_id=config.force_sensor.node_id,
            direction=config.force_sensor.direction,
            offset_n=config.force_sensor.offset_n,
            stale_after_s=config.safety.link_stale_ticks * period,
        )
    timeout = config.loop.bus_read_timeout_ms / 1000.0
    return DynamixelCanBusConfig(
        joint_names=config.joint_names,
        dynamixel=chain,
        encoders=encoders,
        can_bus_kwargs=connection.can_bus_kwargs,
        force_sensor=force,
        link_timeout_s=LOCKSTEP_LINK_TIMEOUT_S if lockstep else timeout,
    )


def make_bus(
    config: Config, connection: Connection, clock: Callable[[], float] | None = None
) -> DynamixelCanBus:
    try:
        bus_cfg = bus_config(config, connection)
    except ValueError as exc:
        raise ConfigError(f"{config.source}: {exc}") from exc
    if clock is None:
        import time

        clock = time.monotonic
    return DynamixelCanBus(bus_cfg, clock=clock)


def current_limit_a(config: Config) -> list[float]:
    """The current caps the configuration sets (A); NaN where it leaves the device's own, which
    the bus then reports at open (`JointBus.current_limits_a`)."""
    return [j.torque_limit_a if j.torque_limit_a is not None else math.nan for j in config.joints]
