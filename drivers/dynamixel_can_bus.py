"""The robot's JointBus: Dynamixel Pro chains on RS-485 + link encoders on CAN.

A robot may have several of each: one `DynamixelChain` per serial port and one
`LinkEncoderReader` per CAN channel. `BusLayout` says, once, which chain slot and which encoder
slot each joint uses (the idea of vulp's `ServoLayout`); everything else works per joint.

One tick reads in this order, on hardware and on the emulated testbed alike:
    1. SYNC on every CAN channel: every link encoder latches its position (and a force sensor
       its force) and starts sending its TPDO;
    2. one Dynamixel sync read of the state block per chain (position, velocity, current,
       hardware error status, torque enable), while the TPDOs arrive (the CAN adapter buffers
       them);
    3. collect the TPDOs that answer each SYNC (bounded wait; usually all there already).
The CAN frames and the RS-485 packets overlap instead of adding up: with twelve joints, the
TPDOs take ~1.8 ms at 1 Mbit/s and the sync read ~0.5 ms at 3 Mbit/s plus the USB adapter's
latency (docs/humanoid.md, "the tick budget"). The emulated robot in lock-step advances its
physics on the SYNC and answers the sync read only after it (it reads CAN first), so the
motor and link readings are of the same instant there; on hardware they are < 1 ms apart.
`write()` is one Dynamixel sync write of the goal positions per chain.

A joint without a link encoder (`DynamixelCanBusConfig.without_link_encoder`: a stock arm)
reports its motor angle through the gear as its link angle (theta = theta_m: the gear's
deflection is not observed), valid when the actuator's reading is.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import can
import numpy as np

from drivers.canbus import (
    ForceSensorConfig,
    ForceTorqueSensorConfig,
    LinkEncoderConfig,
    LinkEncoderReader,
)
from drivers.canbus.read_ahead import slcan_read_ahead
from drivers.canbus.readings import LinkReading
from drivers.dynamixel import DynamixelChain, DynamixelChainConfig, DynamixelState, actuator_fault
from drivers.joint_bus import (
    ActuatorFault,
    BusError,
    BusFault,
    DeviceRole,
    Diagnostic,
    JointBus,
    JointDevices,
    JointSample,
    add_wrench,
)
from drivers.peer_wait import PeerActivity, PeerWait


@dataclass(frozen=True)
class CanChannelConfig:
    """One CAN channel: how to open it (`can.Bus(**bus_kwargs)`) and the sensors on it."""

    name: str
    bus_kwargs: dict[str, Any]
    encoders: tuple[LinkEncoderConfig, ...]
    force_sensor: ForceSensorConfig | None = None
    force_torque_sensors: tuple[ForceTorqueSensorConfig, ...] = ()

    @property
    def description(self) -> str:
        return f"{self.bus_kwargs.get('interface')}:{self.bus_kwargs.get('channel')}"


@dataclass(frozen=True)
class BusLayout:
    """Which device serves which joint: (chain, slot) for the actuator, (channel, slot) for
    the link encoder (None: the joint has none), per joint in `joint_names` order. Built from
    the device names."""

    joint_names: tuple[str, ...]
    actuator_slot: tuple[tuple[int, int], ...]
    encoder_slot: tuple[tuple[int, int] | None, ...]

    @classmethod
    def from_names(
        cls,
        joint_names: Sequence[str],
        chains: Sequence[DynamixelChainConfig],
        channels: Sequence[CanChannelConfig],
        without_link_encoder: Sequence[str] = (),
    ) -> BusLayout:
        actuators = {
            joint.name: (c, s)
            for c, chain in enumerate(chains)
            for s, joint in enumerate(chain.joints)
        }
        encoders = {
            enc.name: (c, s)
            for c, channel in enumerate(channels)
            for s, enc in enumerate(channel.encoders)
        }
        names = tuple(joint_names)
        bare = set(without_link_encoder)
        if bare - set(names):
            raise ValueError(f"joints without a link encoder are no joints: {sorted(bare)}")
        sensed = tuple(name for name in names if name not in bare)
        for what, table, count, needing in (
            ("actuator", actuators, sum(len(c.joints) for c in chains), names),
            ("link encoder", encoders, sum(len(c.encoders) for c in channels), sensed),
        ):
            missing = [name for name in needing if name not in table]
            extra = sorted(set(table) - set(needing))
            if missing or extra or count != len(needing):
                raise ValueError(
                    f"every joint needs exactly one {what}: joints {list(needing)}, "
                    f"{what}s named {sorted(table)}"
                    + (f"; missing for {missing}" if missing else "")
                    + (f"; not a joint: {extra}" if extra else "")
                )
        return cls(names, tuple(actuators[n] for n in names), tuple(encoders.get(n) for n in names))

    def joints_of_chain(self, chain: int) -> np.ndarray:
        """Joint indices of a chain's slots, in slot order."""
        pairs = sorted((slot, j) for j, (c, slot) in enumerate(self.actuator_slot) if c == chain)
        return np.array([j for _, j in pairs], dtype=np.intp)

    def joints_of_channel(self, channel: int) -> np.ndarray:
        pairs = sorted(
            (where[1], j)
            for j, where in enumerate(self.encoder_slot)
            if where and where[0] == channel
        )
        return np.array([j for _, j in pairs], dtype=np.intp)

    @property
    def joints_without_link_encoder(self) -> np.ndarray:
        return np.array([j for j, where in enumerate(self.encoder_slot) if where is None], np.intp)


@dataclass(frozen=True)
class DynamixelCanBusConfig:
    """Everything the robot's bus needs; `hil` builds it from the configuration file."""

    joint_names: tuple[str, ...]
    chains: tuple[DynamixelChainConfig, ...]
    can_channels: tuple[CanChannelConfig, ...]
    link_timeout_s: float = 0.002  # how long a tick waits for the TPDOs after SYNC
    # links_after_actuators: collect the actuators' replies first, then the link encoders'.
    # For a lock-step emulator, which sends a SYNC's TPDOs before it answers the sync read:
    # once the actuators answered, a TPDO not there yet never comes, so a dead encoder costs
    # link_timeout_s (small) instead of a wait sized for a slow emulator. On hardware the
    # TPDOs come first (within ~0.3 ms of the SYNC) and are collected first.
    links_after_actuators: bool = False
    allow_torque_off: bool = False  # may open() turn torque off to rewrite EEPROM items?
    # read_only: open() writes nothing to the actuators (no EEPROM or RAM configuration) and
    # every command raises BusError; the link encoders are still brought up (NMT, TPDO
    # settings), which they need to send their position at all.
    read_only: bool = False
    # joints with no link encoder: their motor angle stands for the link's (module docstring)
    without_link_encoder: tuple[str, ...] = ()
    layout: BusLayout = field(init=False)

    def __post_init__(self) -> None:
        if not self.chains or not self.can_channels:
            raise ValueError("the bus needs at least one Dynamixel chain and one CAN channel")
        if not self.link_timeout_s > 0:
            raise ValueError("link_timeout_s must be > 0")
        layout = BusLayout.from_names(
            self.joint_names, self.chains, self.can_channels, self.without_link_encoder
        )
        object.__setattr__(self, "layout", layout)


class DynamixelCanBus(JointBus):
    """Dynamixel chains + CAN link encoders as one JointBus (SI units).

    peer: what the process behind the buses is doing, when they are served by one on this
    machine (an emulator in lock-step): every wait for an answer - at open, on every tick, at
    torque off - then goes on past its timeout while that process works, and ends as on
    hardware when it is stopped, gone or idle (drivers/peer_wait.py). None (hardware, or an
    emulator on the wall clock): the timeouts as configured."""

    def __init__(
        self,
        config: DynamixelCanBusConfig,
        clock: Callable[[], float] = time.monotonic,
        peer: PeerActivity | None = None,
    ):
        self.config = config
        self.joint_names = config.joint_names
        self.clock = clock
        self.peer = peer
        self.chains = tuple(DynamixelChain(chain, self._patience()) for chain in config.chains)
        self.readers: list[LinkEncoderReader] = []
        self._chain_joints = [config.layout.joints_of_chain(c) for c in range(len(self.chains))]
        self._channel_joints = [
            config.layout.joints_of_channel(c) for c in range(len(config.can_channels))
        ]
        identity = np.arange(len(config.joint_names))
        self._without_link = config.layout.joints_without_link_encoder
        self._in_joint_order = (
            len(self._chain_joints) == len(self._channel_joints) == 1
            and np.array_equal(self._chain_joints[0], identity)
            and np.array_equal(self._channel_joints[0], identity)
        )
        self._closed = False

    # --- lifecycle -------------------------------------------------------------------------
    def open(self) -> None:
        try:
            for chain in self.chains:
                chain.open(
                    allow_torque_off=self.config.allow_torque_off,
                    read_only=self.config.read_only,
                )
            for channel in self.config.can_channels:
                try:
                    # slcan (an emulated adapter's pty, a CANable): frames read whole
                    can_bus = can.Bus(**slcan_read_ahead(channel.bus_kwargs))
                except (can.CanError, OSError, ValueError) as exc:
                    raise BusError(f"cannot open the CAN bus {channel.description}: {exc}") from exc
                reader = LinkEncoderReader(
                    can_bus,
                    channel.encoders,
                    force_sensor=channel.force_sensor,
                    force_torque_sensors=channel.force_torque_sensors,
                    clock=self.clock,
                    bus_description=channel.description,
                    patience=self._patience(),
                )
                self.readers.append(reader)  # owns can_bus from here on
                reader.open()
        except BaseException:
            self.close()
            raise

    def _patience(self) -> PeerWait | None:
        """One wait's patience (each chain and channel has its own)."""
        return PeerWait(self.peer) if self.peer is not None else None

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        errors = []
        for closable in (*self.readers, *self.chains):
            try:
                closable.close()
            except Exception as exc:  # noqa: BLE001 - release everything, report after
                errors.append(str(exc))
        if errors:
            raise BusError("while closing the bus: " + "; ".join(errors))

    # --- the 200 Hz path -------------------------------------------------------------------
    def read(self) -> JointSample:
        self.start_read()
        return self.finish_read()

    def start_read(self) -> None:
        """SYNC on every CAN channel, then the SYNC_READ on every chain (in that order: the
        lock-step emulator steps its plant on the SYNC, and answers a read sent after it with
        the new state)."""
        if len(self.readers) != len(self.config.can_channels):
            raise BusError("read() before open()")
        try:
            for reader in self.readers:
                reader.send_sync()
            for chain in self.chains:
                chain.request_state()
        except (can.CanError, OSError) as exc:  # a port that vanished (serial errors are OSError)
            raise BusError(f"the bus failed while reading: {exc}") from exc

    def finish_read(self) -> JointSample:
        """The link encoders' answers first (they come within a few hundred microseconds of
        the SYNC), then the Dynamixel replies (held ~1 ms longer by the USB adapter); the other
        way round with `links_after_actuators` (a lock-step emulator)."""
        try:
            if self.config.links_after_actuators:
                motors = [chain.receive_state() for chain in self.chains]
                links = [reader.collect(self.config.link_timeout_s) for reader in self.readers]
            else:
                links = [reader.collect(self.config.link_timeout_s) for reader in self.readers]
                motors = [chain.receive_state() for chain in self.chains]
        except (can.CanError, OSError) as exc:  # a port that vanished (serial errors are OSError)
            raise BusError(f"the bus failed while reading: {exc}") from exc
        if self._in_joint_order:
            return self._sample_in_joint_order(motors[0], links[0])
        sample = JointSample.empty(self.n_joints)
        sample.timestamp_s = links[0].sync_time_s
        self._add_faults(sample, motors, links)
        temperature = np.full(self.n_joints, np.nan)
        voltage = np.full(self.n_joints, np.nan)
        sample.diagnostics[Diagnostic.ACTUATOR_TEMPERATURE_C] = temperature
        sample.diagnostics[Diagnostic.ACTUATOR_INPUT_VOLTAGE_V] = voltage
        for joints, motor in zip(self._chain_joints, motors, strict=True):
            temperature[joints] = motor.temperature_c
            voltage[joints] = motor.input_voltage_v
            sample.motor_angle_rad[joints] = motor.position_rad
            sample.motor_velocity_rad_s[joints] = motor.velocity_rad_s
            sample.motor_current_a[joints] = motor.current_a
            sample.fault_code[joints] = motor.hardware_error
            sample.torque_enabled[joints] = motor.torque_enabled
            sample.motor_valid[joints] = motor.valid
        for joints, link in zip(self._channel_joints, links, strict=True):
            sample.link_angle_rad[joints] = link.angles_rad
            sample.link_valid[joints] = link.valid
            sample.link_age_s[joints] = link.age_s
        bare = self._without_link
        if bare.size:  # no link encoder: the motor angle through the gear stands for it
            sample.link_angle_rad[bare] = sample.motor_angle_rad[bare]
            sample.link_valid[bare] = sample.motor_valid[bare]
            sample.link_age_s[bare] = 0.0
        return sample

    def _sample_in_joint_order(self, motor: DynamixelState, link: LinkReading) -> JointSample:
        """One chain and one CAN channel, each in joint order: the sample takes the readings'
        arrays as they are (new ones every read)."""
        diagnostics = {
            Diagnostic.ACTUATOR_TEMPERATURE_C: motor.temperature_c,
            Diagnostic.ACTUATOR_INPUT_VOLTAGE_V: motor.input_voltage_v,
        }
        sample = JointSample(
            timestamp_s=link.sync_time_s,
            motor_angle_rad=motor.position_rad,
            link_angle_rad=link.angles_rad,
            motor_velocity_rad_s=motor.velocity_rad_s,
            motor_current_a=motor.current_a,
            actuator_fault=np.zeros(self.n_joints, dtype=np.uint8),
            fault_code=motor.hardware_error.astype(np.int64),
            torque_enabled=motor.torque_enabled,
            motor_valid=motor.valid,
            link_valid=link.valid,
            link_age_s=link.age_s,
            diagnostics=diagnostics,
        )
        self._add_faults(sample, [motor], [link])
        return sample

    def _add_faults(
        self, sample: JointSample, motors: list[DynamixelState], links: list[LinkReading]
    ) -> None:
        """The readings' faults, bus errors, notes and named sensors in the sample."""
        for joints, chain, motor in zip(self._chain_joints, self.chains, motors, strict=True):
            if np.count_nonzero(motor.hardware_error):
                for slot in np.flatnonzero(motor.hardware_error).tolist():
                    sample.actuator_fault[joints[slot]] = actuator_fault(
                        int(motor.hardware_error[slot])
                    )
            if np.count_nonzero(motor.valid) == motor.valid.size:
                continue
            for slot in np.flatnonzero(~motor.valid).tolist():
                dxl_id = motor.dxl_ids[slot]
                reason = motor.invalid_reasons.get(dxl_id) or "; ".join(motor.errors) or "invalid"
                joint = int(joints[slot])
                sample.bus_errors.append(
                    BusFault(joint, DeviceRole.ACTUATOR, self._actuator_label(chain, slot), reason)
                )
        for joints, reader, link in zip(self._channel_joints, self.readers, links, strict=True):
            if np.count_nonzero(link.valid) != link.valid.size:
                for slot in np.flatnonzero(~link.valid).tolist():
                    node = reader.encoder_configs[slot].node_id
                    sample.bus_errors.append(
                        BusFault(
                            int(joints[slot]),
                            DeviceRole.LINK_SENSOR,
                            f"link encoder node {node}",
                            "no answer to SYNC",
                        )
                    )
            sample.notes.extend(link.events)
            if link.force is not None:
                sample.extra["contact_force_n"] = link.force.force_n
            for wrench in link.wrenches:
                add_wrench(sample.extra, wrench.label, wrench.force_n, wrench.torque_nm)

    def write(self, goal_motor_angle_rad: np.ndarray) -> None:
        goal = np.asarray(goal_motor_angle_rad, dtype=float)
        try:
            for joints, chain in zip(self._chain_joints, self.chains, strict=True):
                chain.write_goals(goal[joints])
        except OSError as exc:
            raise BusError(f"the bus failed while writing goals: {exc}") from exc

    # --- torque ----------------------------------------------------------------------------
    def enable(self) -> None:
        for chain in self.chains:
            chain.enable()

    def disable(self) -> None:
        errors = []
        for chain in self.chains:  # every chain gets its try, whatever the others did
            try:
                chain.disable()
            except Exception as exc:  # noqa: BLE001 - collected and raised below
                errors.append(f"{chain.config.port}: {exc}")
        if errors:
            raise BusError("torque off failed on " + "; ".join(errors))

    def reboot(self, joints: Sequence[int] | None = None) -> dict[str, ActuatorFault]:
        selected = range(self.n_joints) if joints is None else joints
        result: dict[str, ActuatorFault] = {}
        for c, chain in enumerate(self.chains):
            mine = [j for j in selected if self.config.layout.actuator_slot[j][0] == c]
            if not mine:
                continue
            ids = [chain.dxl_ids[self.config.layout.actuator_slot[j][1]] for j in mine]
            statuses = chain.reboot(ids)
            for j, dxl_id in zip(mine, ids, strict=True):
                result[self.joint_names[j]] = actuator_fault(statuses[dxl_id].bits)
        return result

    # --- what it is ------------------------------------------------------------------------
    def current_limits_a(self) -> np.ndarray:
        limits = np.full(self.n_joints, np.nan)
        for joints, chain in zip(self._chain_joints, self.chains, strict=True):
            if chain.devices:
                limits[joints] = [device.current_limit_a for device in chain.devices]
        return limits

    def devices(self) -> tuple[JointDevices, ...]:
        layout = self.config.layout
        out = []
        for j in range(self.n_joints):
            chain, slot = layout.actuator_slot[j]
            link_sensor = "none (the motor encoder through the gear)"
            if (where := layout.encoder_slot[j]) is not None:
                node = self.config.can_channels[where[0]].encoders[where[1]].node_id
                link_sensor = f"link encoder node {node}"
            out.append(
                JointDevices(
                    actuator=self._actuator_label(self.chains[chain], slot),
                    link_sensor=link_sensor,
                )
            )
        return tuple(out)

    def describe(self) -> dict[str, object]:
        return {
            "joints": list(self.joint_names),
            "dynamixel": [
                {
                    "port": chain.config.port,
                    "baudrate": chain.config.baudrate,
                    "ids": list(chain.dxl_ids),
                }
                for chain in self.chains
            ],
            "can": [
                {
                    **{
                        k: v for k, v in channel.bus_kwargs.items() if k in ("interface", "channel")
                    },
                    "encoder_node_ids": [e.node_id for e in channel.encoders],
                    "force_sensor_node_id": (
                        channel.force_sensor.node_id if channel.force_sensor else None
                    ),
                }
                for channel in self.config.can_channels
            ],
        }

    @staticmethod
    def _actuator_label(chain: DynamixelChain, slot: int) -> str:
        return f"actuator {chain.dxl_ids[slot]}"
