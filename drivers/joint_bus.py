"""The abstract joint bus: what the loop sees of a set of flexible joints, in SI units.

Modelled on python-can's `BusABC`: one small abstract class, implementations chosen by
configuration, the same loop code for the real testbed, the emulated one and the in-process one.
Nothing here is specific to a vendor: an actuator's own fault codes are translated into
`ActuatorFault` by its driver, and a device that did not answer is reported as a `BusFault`.
"""

from __future__ import annotations

import abc
import enum
from dataclasses import dataclass, field

import numpy as np


class ActuatorFault(enum.IntFlag):
    """Why an actuator's own protection stopped it (or is about to): vendor-neutral.

    A driver maps its device's codes onto these (the Dynamixel bits: drivers/dynamixel/
    hardware_error.py) and keeps the device's own code beside them for the message.
    """

    OVERLOAD = 0x01
    OVERHEATING = 0x02
    SUPPLY_VOLTAGE = 0x04
    MOTOR_SENSOR = 0x08
    ELECTRICAL = 0x10
    OTHER = 0x80

    @classmethod
    def describe(cls, flags: int) -> str:
        """'OVERLOAD|OVERHEATING' for the set flags, 'none' for 0."""
        names = [flag.name for flag in cls if flags & flag and flag.name]
        return "|".join(names) if names else "none"


class Diagnostic(enum.StrEnum):
    """Per-joint readings a bus may report beside the control signals (`JointSample.diagnostics`),
    SI units in the name. A bus that cannot read one leaves it out."""

    ACTUATOR_TEMPERATURE_C = "actuator_temperature_c"
    ACTUATOR_INPUT_VOLTAGE_V = "actuator_input_voltage_v"


class DeviceRole(enum.Enum):
    """Which device of a joint a bus fault concerns."""

    ACTUATOR = "actuator"
    LINK_SENSOR = "link sensor"
    OTHER = "other"


@dataclass(frozen=True)
class BusFault:
    """One thing that went wrong on a bus this tick, tied to a joint where it concerns one."""

    joint: int | None  # joint index, None for a bus-wide problem or a sensor of no joint
    role: DeviceRole
    device: str  # e.g. "Dynamixel ID 1 (link)", "link encoder node 5"
    message: str

    def __str__(self) -> str:
        return f"{self.device}: {self.message}"


class BusError(RuntimeError):
    """A joint bus could not be opened, read or written (message says which device and why)."""


@dataclass
class JointSample:
    """One reading of every joint, SI units, arrays of length n_joints.

    A value that could not be read this tick is NaN and its `*_valid` flag is False: the bus
    never reports a silent zero.
    """

    timestamp_s: float
    motor_angle_rad: np.ndarray
    link_angle_rad: np.ndarray
    motor_velocity_rad_s: np.ndarray
    motor_current_a: np.ndarray
    actuator_fault: np.ndarray  # uint8 per joint, ActuatorFault flags (0 = healthy)
    fault_code: np.ndarray  # int per joint: the device's own code for it (for messages)
    torque_enabled: np.ndarray  # bool per joint, as read back from the device
    motor_valid: np.ndarray  # bool per joint: the actuator answered this tick
    link_valid: np.ndarray  # bool per joint: a fresh link-sensor value arrived this tick
    link_age_s: np.ndarray  # seconds since the last fresh link value (0 when fresh)
    bus_errors: list[BusFault] = field(default_factory=list)  # what went wrong this tick
    notes: list[str] = field(default_factory=list)  # bus events worth logging (boot-up, EMCY)
    extra: dict[str, float] = field(default_factory=dict)  # named sensors, e.g. contact force
    # per-joint arrays by Diagnostic (temperature, supply voltage), NaN where not read this tick
    diagnostics: dict[Diagnostic, np.ndarray] = field(default_factory=dict)

    @classmethod
    def empty(cls, n_joints: int, timestamp_s: float = 0.0) -> JointSample:
        nan = np.full(n_joints, np.nan)
        return cls(
            timestamp_s=timestamp_s,
            motor_angle_rad=nan.copy(),
            link_angle_rad=nan.copy(),
            motor_velocity_rad_s=nan.copy(),
            motor_current_a=nan.copy(),
            actuator_fault=np.zeros(n_joints, dtype=np.uint8),
            fault_code=np.zeros(n_joints, dtype=np.int64),
            torque_enabled=np.zeros(n_joints, dtype=bool),
            motor_valid=np.zeros(n_joints, dtype=bool),
            link_valid=np.zeros(n_joints, dtype=bool),
            link_age_s=np.full(n_joints, np.inf),
        )

    @property
    def deflection_rad(self) -> np.ndarray:
        """Link minus motor angle: positive when the load leads the motor."""
        return self.link_angle_rad - self.motor_angle_rad

    def errors_of(self, joint: int, role: DeviceRole) -> list[BusFault]:
        """This tick's bus faults of one joint's device."""
        return [f for f in self.bus_errors if f.joint == joint and f.role is role]


WRENCH_AXES = ("fx_n", "fy_n", "fz_n", "mx_nm", "my_nm", "mz_nm")


def wrench_keys(label: str) -> tuple[str, ...]:
    """The `JointSample.extra` keys of a six-axis force/torque sensor named `label`:
    `<label>_fx_n` ... `<label>_mz_nm` (its frame, SI)."""
    return tuple(f"{label}_{axis}" for axis in WRENCH_AXES)


def add_wrench(
    extra: dict[str, float], label: str, force_n: np.ndarray, torque_nm: np.ndarray
) -> None:
    """Put a wrench reading into a sample's `extra` under `wrench_keys(label)`."""
    for key, value in zip(wrench_keys(label), (*force_n, *torque_nm), strict=True):
        extra[key] = float(value)


@dataclass(frozen=True)
class JointDevices:
    """How one joint's devices are named in messages (e.g. "Dynamixel ID 1 on /dev/ttyUSB0")."""

    actuator: str
    link_sensor: str


class JointBus(abc.ABC):
    """A set of n flexible joints: read state, write goal motor angles.

    Lifecycle: `open()` checks and configures the devices without enabling torque; `enable()`
    turns torque on; each tick calls `read()` (or `start_read()` ... `finish_read()`) then
    `write()`; `disable()` turns torque off;
    `close()` releases the ports (it does not change the torque state: the caller decides).
    Use it as a context manager to guarantee `close()`.
    """

    joint_names: tuple[str, ...]

    @property
    def n_joints(self) -> int:
        return len(self.joint_names)

    @abc.abstractmethod
    def open(self) -> None:
        """Connect, identify every device (refuse a wrong model) and configure it. No torque."""

    @abc.abstractmethod
    def read(self) -> JointSample:
        """Sample every joint once (one bus transaction per device family)."""

    def start_read(self) -> None:
        """The first half of `read()`: send the requests, do not wait for the answers.

        A loop may do other work while the answers travel (on the testbed the Dynamixel reply
        spends ~1 ms in the USB adapter alone), then call `finish_read()`. A bus that cannot
        split its read does it all in `finish_read()` (this default)."""
        return None  # the default sends nothing ahead

    def finish_read(self) -> JointSample:
        """The second half of `read()`: the answers to the last `start_read()`."""
        return self.read()

    @abc.abstractmethod
    def write(self, goal_motor_angle_rad: np.ndarray) -> None:
        """Send one goal motor angle per joint (one bus transaction)."""

    @abc.abstractmethod
    def enable(self) -> None:
        """Torque on for every joint."""

    @abc.abstractmethod
    def disable(self) -> None:
        """Torque off for every joint (best effort on every joint even if one fails)."""

    @abc.abstractmethod
    def reboot(self, joints: list[int] | None = None) -> dict[str, ActuatorFault]:
        """Reboot the actuators (all, or these joint indices); clears latched faults.

        Returns, per rebooted joint name, the faults its actuator reports afterwards.
        """

    @abc.abstractmethod
    def close(self) -> None:
        """Release ports and threads. Safe to call twice."""

    @abc.abstractmethod
    def devices(self) -> tuple[JointDevices, ...]:
        """Each joint's devices, named for messages (one entry per joint)."""

    def current_limits_a(self) -> np.ndarray:
        """Each actuator's current cap [A] as the device reports it (after open()); NaN where
        the bus cannot tell. The supervisor's overload guard compares the current against it."""
        return np.full(self.n_joints, np.nan)

    def describe(self) -> dict[str, object]:
        """What this bus drives (ports, IDs, node IDs), for the run's record."""
        return {"joints": list(self.joint_names)}

    def __enter__(self) -> JointBus:
        self.open()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()
