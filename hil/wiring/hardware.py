"""From the configuration file to the drivers: the JointBus a run talks to.

The same function builds the bus for the real robot and for an emulated one; only the ports
differ (`Connection`). Device checks (ID ranges, baud rates, current limits, position ranges)
are the drivers' own: `hil.wiring.checks.check_devices` builds every driver configuration
without opening a port, so a bad value is refused before anything is sent, in every mode.

In lock-step emulation the timeouts are widened: the emulator answers every request, but a
loaded machine may delay it by tens of milliseconds, and a timeout that fired on such a delay
would make the run depend on the machine's load. Where the emulator's process is known (an
embedded emulator), every wait of the bus - at open, on tick 0 and every tick, at torque off -
also goes on past its timeout while that process works (runnable or using the CPU:
hil/wiring/process_activity.py, drivers/peer_wait.py), and ends when it is stopped, gone or
idle: a lock-step run is the same on a loaded machine as alone. On hardware and on the wall
clock the timeouts are as configured.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

from drivers.canbus import (
    RLC2IC_MR075_COUNTS_PER_REV,
    ForceSensorConfig,
    ForceTorqueSensorConfig,
    LinkEncoderConfig,
)
from drivers.dynamixel import DynamixelChainConfig, DynamixelJointConfig, model_number
from drivers.dynamixel_can_bus import CanChannelConfig, DynamixelCanBus, DynamixelCanBusConfig
from hil.config import Config, ConfigError, JointSection
from hil.wiring.connection import Connection
from hil.wiring.process_activity import ProcessActivity

LOCKSTEP_LATENCY_TIMER_MS = 50.0
# Lock-step: the emulator sends a SYNC's TPDOs before it answers the sync read, and the bus
# collects the actuators first (`links_after_actuators`): the TPDOs are in the port's buffer
# by then, and one that is not never comes (a dead encoder costs this, not a slow emulator's
# allowance: 0.2 s a tick before).
LOCKSTEP_LINK_TIMEOUT_S = 0.005
# An emulator on a shared 2-core machine answers a fresh request 3-7 ms late now and then (a
# process scheduling artefact, not a property of the bus): with the hardware's 1 ms latency
# setting (~4 ms reply timeout) such replies would count as lost. Real-time emulation keeps the
# wire timing and widens only this allowance.
EMULATED_LATENCY_TIMER_MS = 10.0


def encoder_counts_per_rev(joint: JointSection) -> int:
    """The joint's link-encoder resolution: configured, or the driver's RLC2IC + MR075 figure."""
    return joint.encoder_counts_per_rev or RLC2IC_MR075_COUNTS_PER_REV


def _latency_timer_ms(configured: float, connection: Connection) -> float:
    if connection.lockstep:
        return LOCKSTEP_LATENCY_TIMER_MS
    if connection.emulated:
        return EMULATED_LATENCY_TIMER_MS
    return configured


def _model_number(name: str, key: str) -> int:
    try:
        return model_number(name)
    except ValueError as exc:
        raise ValueError(f"{key}: {exc}") from None


def _chain_config(config: Config, chain: str, connection: Connection) -> DynamixelChainConfig:
    section = next(d for d in config.dynamixel if d.name == chain)
    endpoint = connection.dynamixel[chain]
    joints = tuple(
        DynamixelJointConfig(
            dxl_id=j.dynamixel_id,
            model_number=(
                None
                if j.actuator is None
                else _model_number(j.actuator, f"[[joint]] {j.name!r} actuator")
            ),
            direction=j.motor_direction,
            offset_rad=j.motor_offset_rad,
            min_position_rad=j.min_angle_rad,
            max_position_rad=j.max_angle_rad,
            torque_limit_a=j.torque_limit_a,
            position_p_gain=j.position_p_gain,
            velocity_p_gain=j.velocity_p_gain,
            velocity_i_gain=j.velocity_i_gain,
            name=j.name,
        )
        for j in config.joints
        if config.chain_of(j) == chain
    )
    return DynamixelChainConfig(
        port=endpoint.port,
        baudrate=endpoint.baudrate,
        joints=joints,
        model_number=_model_number(section.model, f"[[dynamixel]] {section.name!r} model"),
        return_delay_time_us=section.return_delay_time_us,
        latency_timer_ms=_latency_timer_ms(section.latency_timer_ms, connection),
    )


def _channel_config(config: Config, channel: str, connection: Connection) -> CanChannelConfig:
    stale_after_s = config.safety.link_stale_ticks * config.loop.period_s
    encoders = tuple(
        LinkEncoderConfig(
            node_id=j.encoder_node_id,
            counts_per_rev=encoder_counts_per_rev(j),
            offset_rad=j.encoder_offset_rad,
            direction=j.encoder_direction,
            stale_after_s=stale_after_s,
            name=j.name,
        )
        for j in config.joints
        if config.channel_of(j) == channel and j.encoder_node_id
    )
    sensor = config.force_sensor
    force = None
    if sensor.node_id and config.force_sensor_channel == channel:
        force = ForceSensorConfig(
            node_id=sensor.node_id,
            direction=sensor.direction,
            offset_n=sensor.offset_n,
            stale_after_s=stale_after_s,
        )
    wrenches = tuple(
        ForceTorqueSensorConfig(
            node_id=f.node_id,
            label=f.name,
            force_offset_n=f.force_offset_n,
            torque_offset_nm=f.torque_offset_nm,
            stale_after_s=stale_after_s,
        )
        for f in config.force_torque_sensors
        if config.channel_of(f) == channel
    )
    return CanChannelConfig(channel, dict(connection.can[channel]), encoders, force, wrenches)


def bus_config(
    config: Config, connection: Connection, *, read_only: bool = False
) -> DynamixelCanBusConfig:
    """The drivers' configuration of the whole bus; ValueError from a driver names the device.

    read_only: a bus that writes nothing to the actuators (`hil monitor`, `hil calibrate`)."""
    return DynamixelCanBusConfig(
        joint_names=config.joint_names,
        chains=tuple(_chain_config(config, d.name, connection) for d in config.dynamixel),
        can_channels=tuple(_channel_config(config, c.name, connection) for c in config.can),
        link_timeout_s=(
            LOCKSTEP_LINK_TIMEOUT_S
            if connection.lockstep
            else config.loop.bus_read_timeout_ms / 1000.0
        ),
        links_after_actuators=connection.lockstep,
        read_only=read_only,
        without_link_encoder=config.joints_without_link_encoder,
    )


def make_bus(
    config: Config,
    connection: Connection,
    clock: Callable[[], float] | None = None,
    *,
    read_only: bool = False,
) -> DynamixelCanBus:
    try:
        bus_cfg = bus_config(config, connection, read_only=read_only)
    except ValueError as exc:
        raise ConfigError(f"{config.source}: {exc}") from exc
    peer = None
    if connection.lockstep and connection.emulator_pid is not None:
        peer = ProcessActivity(connection.emulator_pid)
    return DynamixelCanBus(bus_cfg, clock=clock or time.monotonic, peer=peer)


def configured_current_limits_a(config: Config) -> list[float]:
    """The current caps the configuration sets (A); NaN where it leaves the device's own, which
    the bus then reports at open (`JointBus.current_limits_a`)."""
    return [j.torque_limit_a if j.torque_limit_a is not None else math.nan for j in config.joints]


def describe_connection(connection: Connection) -> dict[str, Any]:
    """The ports a run drives, after every override: for meta.json and the banner."""
    return connection.record()
