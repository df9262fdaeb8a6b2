"""What the emulator builds: the spec `hil` writes (from the configuration file and an
experiment's world) and the emulator process reads (as JSON: sim_backend/spec_json.py)."""

from __future__ import annotations

import enum
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from sim_backend.canbus.encoder_node import RLC2IC_NOISE_COUNTS_RMS
from sim_backend.canbus.force_sensor_node import FORCE_SENSOR_NOISE_N_RMS
from sim_backend.canbus.slave import DEFAULT_BOOTUP_DELAY_S
from sim_backend.dynamixel import device_model
from sim_backend.dynamixel.models import DEFAULT_MODEL
from sim_backend.plant import TestbedPlantParams
from sim_backend.scenario import Scenario
from sim_backend.servo import H54ServoParams

CLOCKS = ("lockstep", "realtime")


class HardwareKind(enum.StrEnum):
    """Which emulated hardware a spec builds (sim_backend/robots.py builds each). hil's robots
    map onto these (hil/robots/): the emulator knows kinds of hardware, not robots' names."""

    SINGLE_LINKS = "single-links"  # a MuJoCo plant per joint behind its firmware: the testbed
    HUMANOID = "humanoid"  # a legged robot on one MuJoCo model, from `humanoid` (DYROS-JET)


ROBOTS = tuple(HardwareKind)


@dataclass(frozen=True)
class FloorBox:
    """A rigid box lying on the floor (an object the robot may step on): the centre of its
    footprint on the ground (x, y) [m] and its full size (x, y, height) [m], axis-aligned."""

    centre_m: tuple[float, float]
    size_m: tuple[float, float, float]

    def __post_init__(self) -> None:
        centre = tuple(float(v) for v in self.centre_m)
        size = tuple(float(v) for v in self.size_m)
        if len(centre) != 2 or not all(math.isfinite(v) for v in centre):
            raise ValueError(f"a floor box's centre_m must be 2 finite numbers, got {centre}")
        if len(size) != 3 or not all(math.isfinite(v) and v > 0 for v in size):
            raise ValueError(f"a floor box's size_m must be 3 finite sizes > 0, got {size}")
        object.__setattr__(self, "centre_m", centre)
        object.__setattr__(self, "size_m", size)

    @property
    def height_m(self) -> float:
        return self.size_m[2]


@dataclass(frozen=True)
class HumanoidSpec:
    """What the emulator needs beyond the buses to build the humanoid.

    urdf_text: the robot description (the same the host's model reads).
    ft_sensor_node_ids: the left and right foot's force/torque node IDs (0: none).
    initial_leg_angles_rad: the posture the robot is placed in, standing, at power-on.
    truth: RobotTruthParams overrides (plain values; the H54 servo comes from the spec's servo).
    floor_boxes: rigid boxes on the floor (objects the robot may step on), none by default.
    """

    urdf_text: str
    ft_sensor_node_ids: tuple[int, int]
    initial_leg_angles_rad: tuple[float, ...]
    support_feet: tuple[int, ...] = (0, 1)
    truth: Mapping[str, Any] = field(default_factory=dict)
    floor_boxes: tuple[FloorBox, ...] = ()


@dataclass(frozen=True)
class EmulatedJointSpec:
    """One emulated joint: its bus addresses, how its sensors are mounted, and its actuator's
    model (an e-Manual name of the DYNAMIXEL PRO family, sim_backend/dynamixel/models.py)."""

    dxl_id: int
    encoder_node_id: int
    encoder_counts_per_rev: int = 983_040
    encoder_direction: int = 1
    encoder_offset_rad: float = 0.0
    motor_direction: int = 1
    motor_offset_rad: float = 0.0
    model: str = DEFAULT_MODEL


@dataclass(frozen=True)
class SensorNoise:
    """Measurement noise of the emulated CAN sensors, zero-mean Gaussian before each device's
    rounding, drawn from generators seeded by `EmulatorSpec.seed` (same seed, same values; the
    H54's own Present Current / Velocity noise is in `H54ServoParams`).

    link_encoder_counts_rms: every link encoder's read-head noise [counts rms]; nominal 0.5
        (`sim_backend.canbus.encoder_node`: RLS give no jitter figure; ~1 count of flicker).
    force_sensor_n_rms: the obstacle's force sensor [N rms]; nominal 0.05 N (an assumption: the
        paper names no sensor; `sim_backend.canbus.force_sensor_node`).
    """

    link_encoder_counts_rms: float = RLC2IC_NOISE_COUNTS_RMS
    force_sensor_n_rms: float = FORCE_SENSOR_NOISE_N_RMS

    def __post_init__(self) -> None:
        for name in ("link_encoder_counts_rms", "force_sensor_n_rms"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"sensor noise {name} must be a finite rms >= 0, got {value}")


@dataclass(frozen=True)
class EmulatorSpec:
    """Everything the emulator process needs; `hil` builds it from the configuration file."""

    joints: tuple[EmulatedJointSpec, ...]
    baudrate: int = 3_000_000
    can_bitrate: int = 1_000_000
    force_sensor_node_id: int = 0
    period_s: float = 0.005
    clock: str = "lockstep"
    seed: int = 0
    plant: TestbedPlantParams = field(default_factory=TestbedPlantParams)
    servo: H54ServoParams = field(default_factory=H54ServoParams)
    scenario: Scenario = field(default_factory=Scenario)
    reboot_time_s: float = 0.5
    heartbeat_ms: int = 100
    sensor_noise: SensorNoise = field(default_factory=SensorNoise)
    robot: HardwareKind = HardwareKind.SINGLE_LINKS  # HUMANOID: with `humanoid`
    humanoid: HumanoidSpec | None = None
    usb_latency_timer_s: float = 0.0  # the USB-serial adapter's, realtime only (line.py)
    can_bootup_delay_s: float = DEFAULT_BOOTUP_DELAY_S  # a CAN node's restart after NMT reset

    def __post_init__(self) -> None:
        if not self.joints:
            raise ValueError("the emulator needs at least one joint")
        try:
            object.__setattr__(self, "robot", HardwareKind(self.robot))
        except ValueError:
            raise ValueError(
                f"robot must be one of {[str(r) for r in HardwareKind]}, got {self.robot!r}"
            ) from None
        if (self.robot is HardwareKind.HUMANOID) != (self.humanoid is not None):
            raise ValueError("a humanoid emulator needs its HumanoidSpec, and only it")
        if self.clock not in CLOCKS:
            raise ValueError(f"clock must be one of {CLOCKS}, got {self.clock!r}")
        for joint in self.joints:  # ValueError naming a model not served or the rates it offers
            device_model(joint.model).baud_index(self.baudrate)
        if not self.period_s > 0:
            raise ValueError("period_s must be > 0")
        if not 0 <= self.usb_latency_timer_s <= 0.255:  # FTDI: 1..255 ms
            raise ValueError("usb_latency_timer_s must be in 0..0.255 s")
