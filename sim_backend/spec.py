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
    FIXED_BASE = "urdf-fixed-base"  # any fixed-base robot from its URDF, from `fixed_base`


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
    initial_leg_angles_rad: the posture the robot is placed in, standing, at power-on (or, when
        suspended, the posture it hangs in at power-on).
    truth: RobotTruthParams overrides (plain values; the H54 servo comes from the spec's servo).
    floor_boxes: rigid boxes on the floor (objects the robot may step on), none by default.
    suspended: the robot hung by its pelvis from a gantry (to identify the legs, each free):
        the pelvis fixed in the world at a height where the feet clear the floor
        (sim_backend.humanoid.mjcf.SUSPENSION_HEIGHT_M), support_feet unused.
    """

    urdf_text: str
    ft_sensor_node_ids: tuple[int, int]
    initial_leg_angles_rad: tuple[float, ...]
    support_feet: tuple[int, ...] = (0, 1)
    truth: Mapping[str, Any] = field(default_factory=dict)
    floor_boxes: tuple[FloorBox, ...] = ()
    suspended: bool = False


@dataclass(frozen=True)
class ToolPushSpec:
    """A force [N] (world frame) at the tool point from start_s (scenario time) for duration_s."""

    start_s: float
    duration_s: float
    force_n: tuple[float, float, float]

    def __post_init__(self) -> None:
        force = tuple(float(v) for v in self.force_n)
        if len(force) != 3 or not all(math.isfinite(v) for v in force):
            raise ValueError(f"a tool push's force_n must be 3 finite numbers, got {force}")
        if not (self.start_s >= 0 and self.duration_s > 0):
            raise ValueError("a tool push needs start_s >= 0 and duration_s > 0")
        object.__setattr__(self, "force_n", force)


@dataclass(frozen=True)
class BlockSpec:
    """A rigid box fixed in the world [m] (centre, full size, axis-aligned) that the tool may
    touch, its contact force measured by the CAN force sensor."""

    centre_m: tuple[float, float, float]
    size_m: tuple[float, float, float]

    def __post_init__(self) -> None:
        centre = tuple(float(v) for v in self.centre_m)
        size = tuple(float(v) for v in self.size_m)
        if len(centre) != 3 or not all(math.isfinite(v) for v in centre):
            raise ValueError(f"a block's centre_m must be 3 finite numbers, got {centre}")
        if len(size) != 3 or not all(math.isfinite(v) and v > 0 for v in size):
            raise ValueError(f"a block's size_m must be 3 finite sizes > 0, got {size}")
        object.__setattr__(self, "centre_m", centre)
        object.__setattr__(self, "size_m", size)


@dataclass(frozen=True)
class FixedBaseSpec:
    """What the emulator needs beyond the buses to build a fixed-base robot from its URDF.

    urdf_text: the robot description (the same the host's model reads).
    joint_names: the URDF joints that are flexible joints, one per spec joint, in its order.
    locked_angles_rad: every other movable joint, welded at this angle (0 where not named).
    initial_angles_rad: the link angles it rests at, statically loaded, at power-on.
    tool_link / tool_point_m: the tool: a sphere of tool_radius_m at this point of the link's
        frame, where pushes act and what may touch the block (no tool: "").
    block: a box in the world the tool may touch (None: none).
    tool_pushes: pushes at the tool point (scenario time).
    truth: FixedBaseTruthParams overrides (plain values; sim_backend/fixed_base/params.py).
    """

    urdf_text: str
    joint_names: tuple[str, ...]
    initial_angles_rad: tuple[float, ...]
    locked_angles_rad: Mapping[str, float] = field(default_factory=dict)
    tool_link: str = ""
    tool_point_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    tool_radius_m: float = 0.02
    block: BlockSpec | None = None
    tool_pushes: tuple[ToolPushSpec, ...] = ()
    truth: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if len(self.initial_angles_rad) != len(self.joint_names):
            raise ValueError("a fixed-base robot needs one initial angle per joint")
        if (self.block is not None or self.tool_pushes) and not self.tool_link:
            raise ValueError("a block or a push at the tool needs the robot's tool_link")
        if not (math.isfinite(self.tool_radius_m) and self.tool_radius_m > 0):
            raise ValueError(f"tool_radius_m must be > 0, got {self.tool_radius_m}")


@dataclass(frozen=True)
class EmulatedJointSpec:
    """One emulated joint: its bus addresses (`chain`: which of the spec's RS-485 chains its
    actuator is on), how its sensors are mounted, and its actuator's model (an e-Manual name
    of the DYNAMIXEL PRO family, sim_backend/dynamixel/models.py)."""

    dxl_id: int
    encoder_node_id: int  # 0: the joint has no link encoder (no node on the CAN bus)
    encoder_counts_per_rev: int = 983_040
    encoder_direction: int = 1
    encoder_offset_rad: float = 0.0
    motor_direction: int = 1
    motor_offset_rad: float = 0.0
    model: str = DEFAULT_MODEL
    chain: int = 0


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
    """Everything the emulator process needs; `hil` builds it from the configuration file.

    chain_baudrates: one RS-485 chain (a pty each) per entry, at its baud rate; empty: one
    chain at `baudrate`. Each joint's `chain` is an index into them."""

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
    fixed_base: FixedBaseSpec | None = None
    usb_latency_timer_s: float = 0.0  # the USB-serial adapter's, realtime only (line.py)
    can_bootup_delay_s: float = DEFAULT_BOOTUP_DELAY_S  # a CAN node's restart after NMT reset
    truth_log: str = ""  # where the emulator writes its ground truth per SYNC ("" none)
    chain_baudrates: tuple[int, ...] = ()

    @property
    def chain_bauds(self) -> tuple[int, ...]:
        """Each chain's baud rate (one chain at `baudrate` when `chain_baudrates` is empty)."""
        return tuple(self.chain_baudrates) or (self.baudrate,)

    def joint_baudrate(self, joint: EmulatedJointSpec) -> int:
        """The baud rate of the chain a joint's actuator is on."""
        return self.chain_bauds[joint.chain]

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
        if (self.robot is HardwareKind.FIXED_BASE) != (self.fixed_base is not None):
            raise ValueError("a fixed-base emulator needs its FixedBaseSpec, and only it")
        if self.fixed_base is not None and len(self.fixed_base.joint_names) != len(self.joints):
            raise ValueError("a fixed-base robot names one URDF joint per emulated joint")
        if self.clock not in CLOCKS:
            raise ValueError(f"clock must be one of {CLOCKS}, got {self.clock!r}")
        chains = len(self.chain_bauds)
        for joint in self.joints:  # ValueError naming a model not served or the rates it offers
            if not 0 <= joint.chain < chains:
                raise ValueError(f"joint {joint.dxl_id}: chain {joint.chain} of {chains}")
            device_model(joint.model).baud_index(self.joint_baudrate(joint))
        empty = sorted(set(range(chains)) - {joint.chain for joint in self.joints})
        if empty:
            raise ValueError(f"chains {empty} have no joint")
        if not self.period_s > 0:
            raise ValueError("period_s must be > 0")
        if not 0 <= self.usb_latency_timer_s <= 0.255:  # FTDI: 1..255 ms
            raise ValueError("usb_latency_timer_s must be in 0..0.255 s")
