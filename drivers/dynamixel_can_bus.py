"""The testbed's JointBus: Dynamixel Pro actuators on RS-485 + link encoders on CAN.

One tick reads in this order, on hardware and on the emulated testbed alike:
    1. SYNC on CAN: every link encoder latches its position (and the force sensor its force);
    2. collect the TPDOs that answer this SYNC (bounded wait);
    3. one Dynamixel sync read of the state block (position, velocity, current, hardware error
       status, torque enable).
The encoders answer before the actuators are read because the emulated testbed advances its
physics on SYNC in lock-step mode; on hardware the two readings are then ~0.5 ms apart.
`write()` is one Dynamixel sync write of the goal positions.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import can
import numpy as np

from drivers.canbus import ForceSensorConfig, LinkEncoderConfig, LinkEncoderReader
from drivers.dynamixel import DynamixelChain, DynamixelChainConfig
from drivers.joint_bus import BusError, JointBus, JointSample


@dataclass(frozen=True)
class DynamixelCanBusConfig:
    """Everything the testbed bus needs; `hil` builds it from the configuration file."""

    joint_names: tuple[str, ...]
    dynamixel: DynamixelChainConfig
    encoders: tuple[LinkEncoderConfig, ...]
    can_bus_kwargs: dict[str, Any] = field(default_factory=dict)
    force_sensor: ForceSensorConfig | None = None
    link_timeout_s: float = 0.002  # how long a tick waits for the TPDOs after SYNC
    allow_torque_off: bool = False  # may open() turn torque off to rewrite EEPROM items?

    def __post_init__(self) -> None:
        n = len(self.joint_names)
        if len(self.dynamixel.joints) != n or len(self.encoders) != n:
            raise ValueError(
                f"{n} joints but {len(self.dynamixel.joints)} actuators and "
                f"{len(self.encoders)} link encoders: each joint needs one of each"
            )
        if not self.link_timeout_s > 0:
            raise ValueError("link_timeout_s must be > 0")


class DynamixelCanBus(JointBus):
    """Dynamixel chain + CAN link encoders as one JointBus (SI units)."""

    def __init__(self, config: DynamixelCanBusConfig, clock: Callable[[], float] = time.monotonic):
        self.config = config
        self.joint_names = config.joint_names
        self.clock = clock
        self.chain = DynamixelChain(config.dynamixel)
        self._can_bus: can.BusABC | None = None
        self.encoders: LinkEncoderReader | None = None
        self._closed = False

    def open(self) -> None:
        try:
            self.chain.open(allow_torque_off=self.config.allow_torque_off)
            kwargs = dict(self.config.can_bus_kwargs)
            description = f"{kwargs.get('interface')}:{kwargs.get('channel')}"
            try:
                self._can_bus = can.Bus(**kwargs)
            except (can.CanError, OSError, ValueError) as exc:
                raise BusError(f"cannot open the CAN bus {description}: {exc}") from exc
            self.encoders = LinkEncoderReader(
                self._can_bus,
                self.config.encoders,
                force_sensor=self.config.force_sensor,
                clock=self.clock,
                bus_description=description,
            )
            self.encoders.open()
        except BaseException:
            self.close()
            raise

    def read(self) -> JointSample:
        if self.encoders is None:
            raise BusError("read() before open()")
        n = self.n_joints
        try:
            self.encoders.send_sync()
            link = self.encoders.collect(self.config.link_timeout_s)
            motor = self.chain.read_state()
        except (can.CanError, OSError) as exc:  # a port that vanished (serial errors are OSError)
            raise BusError(f"the testbed bus failed while reading: {exc}") from exc
        sample = JointSample(
            timestamp_s=link.sync_time_s,
            motor_angle_rad=motor.position_rad,
            link_angle_rad=link.angles_rad,
            motor_velocity_rad_s=motor.velocity_rad_s,
            motor_current_a=motor.current_a,
            hardware_error=motor.hardware_error,
            torque_enabled=motor.torque_enabled,
            motor_valid=motor.valid,
            link_valid=link.valid,
            link_age_s=link.age_s,
            bus_errors=list(motor.errors),
        )
        missing = [
            f"link encoder node {self.config.encoders[i].node_id}: no answer to SYNC"
            for i in range(n)
            if not link.valid[i]
        ]
        sample.bus_errors.extend(missing)
        sample.notes.extend(link.events)
        if link.force is not None:
            sample.extra["contact_force_n"] = link.force.force_n
        return sample

    def write(self, goal_motor_angle_rad: np.ndarray) -> None:
        try:
            self.chain.write_goals(goal_motor_angle_rad)
        except OSError as exc:
            raise BusError(f"the testbed bus failed while writing goals: {exc}") from exc

    def enable(self) -> None:
        self.chain.enable()

    def disable(self) -> None:
        self.chain.disable()

    def current_limits_a(self) -> np.ndarray:
        devices = self.chain.devices
        if not devices:
            return super().current_limits_a()
        return np.array([device.current_limit_a for device in devices])

    def reboot(self, joints: Sequence[int] | None = None) -> dict[int, int]:
        ids = self.chain.dxl_ids
        selected = [ids[i] for i in joints] if joints is not None else list(ids)
        statuses = self.chain.reboot(selected)
        return {dxl_id: status.bits for dxl_id, status in statuses.items()}

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        errors = []
        if self.encoders is not None:  # the reader owns the CAN bus and shuts it down
            try:
                self.encoders.close()
            except Exception as exc:  # noqa: BLE001 - release everything, report after
                errors.append(str(exc))
        elif self._can_bus is not None:
            try:
                self._can_bus.shutdown()
            except Exception as exc:  # noqa: BLE001
                errors.append(str(exc))
        try:
            self.chain.close()
        except Exception as exc:  # noqa: BLE001
            errors.append(str(exc))
        if errors:
            raise BusError("while closing the testbed bus: " + "; ".join(errors))
