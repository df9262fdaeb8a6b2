"""The configuration file: one TOML file describes the hardware, the controller and the emulator.

The same file drives the real testbed (`hil run --config FILE`) and its emulation
(`hil emulate --config FILE`): the emulator builds the devices the file describes. A sample for
the paper's testbed ships as `hil/data/testbed.toml` (`hil config` prints it).

Loading is strict: unknown sections or keys, wrong types, duplicate IDs and impossible limits
are reported with the file, the section and the key, and nothing is sent to any device.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
import types
import typing
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from drivers.dynamixel.units import H54_200_S500_R_UNITS

DEFAULT_CONFIG_NAME = "testbed.toml"
# The actuator's position-mode range, from the driver's unit table (device units live there).
H54_POSITION_RANGE_RAD = (
    H54_200_S500_R_UNITS.position_limit_pulses * H54_200_S500_R_UNITS.rad_per_pulse
)


class ConfigError(ValueError):
    """A configuration file is malformed or inconsistent. The message says where and why."""


@dataclass(frozen=True)
class LoopConfig:
    rate_hz: float = 200.0  # Kim et al.: "The control frequency is 200 Hz"
    stop_cycles: int = 5  # hold commands sent at start-up and before shutdown
    bus_read_timeout_ms: float = 2.0  # how long a tick waits for the encoders' TPDOs

    @property
    def period_s(self) -> float:
        return 1.0 / self.rate_hz


@dataclass(frozen=True)
class DynamixelConfig:
    port: str = ""
    baudrate: int = 3_000_000
    model: str = "H54-200-S500-R"
    latency_timer_ms: float = 1.0  # ROBOTIS advise 1 ms on FTDI adapters
    return_delay_time_us: int = 0  # ROBOTIS advise 0 for fast sync reads (default is 500 us)


@dataclass(frozen=True)
class CanConfig:
    interface: str = "socketcan"
    channel: str = "can0"
    bitrate: int = 1_000_000
    options: dict[str, Any] = field(default_factory=dict)  # extra can.Bus(...) keyword args

    def bus_kwargs(self) -> dict[str, Any]:
        kwargs: dict[str, Any] = {"interface": self.interface, "channel": self.channel}
        if self.bitrate:
            kwargs["bitrate"] = self.bitrate
        kwargs.update(self.options)
        return kwargs


@dataclass(frozen=True)
class JointConfig:
    """One flexible joint: its actuator, its link encoder, its limits and its model."""

    name: str
    dynamixel_id: int
    encoder_node_id: int
    encoder_counts_per_rev: int = 983_040  # RLS RLC2IC on MR075: 120 poles x 8192 counts
    encoder_offset_rad: float = 0.0
    encoder_direction: int = 1
    motor_offset_rad: float = 0.0
    motor_direction: int = 1
    min_angle_rad: float = -1.0
    max_angle_rad: float = 1.0
    torque_limit_a: float | None = None  # None: leave the device's Torque Limit
    # The controller's model of this joint (paper Sec. IV-A)
    stiffness_nm_per_rad: float = 2000.0
    damping_nms_per_rad: float = 100.0
    servo_gain_per_s: float = 10.0
    link_inertia_kg_m2: float = 0.376  # Sm = 1 / inertia for the 1-DoF testbed
    gravity_moment_kg_m: float = 0.63  # m * r of link + load, for the gravity compensator


@dataclass(frozen=True)
class ForceSensorConfig:
    node_id: int = 0  # 0: no force sensor
    direction: int = 1  # sign from the sensor's reading to a force pressing the link back
    offset_n: float = 0.0  # the reading with nothing touching (subtracted)


@dataclass(frozen=True)
class ControllerConfig:
    name: str = "gc+lqr+dob"
    kdist: float = 1.0
    q_error: float = 10.0
    q_state: float = 1.0
    r_input: float = 1.0
    dob_cutoff_hz: float = 11.4
    composition: str = "accumulated"
    discretization: str = "euler"


@dataclass(frozen=True)
class SafetyConfig:
    """What the supervisor watches and what it does about it (see README, "Safety")."""

    max_goal_rate_rad_s: float = 2.0
    max_deflection_rad: float = 0.06
    current_guard: bool = True
    current_guard_fraction: float = 0.8
    current_guard_time_s: float = 0.6
    current_guard_backoff_rad: float = 0.05
    link_stale_ticks: int = 4
    bus_error_ticks: int = 3
    overrun_limit: int = 20
    on_hardware_error: str = "torque_off"
    on_deflection: str = "hold"
    on_current: str = "back_off"
    on_link_stale: str = "hold"
    on_bus_error: str = "torque_off"
    on_overrun: str = "hold"
    on_exit: str = "torque_off"
    # The link-encoder noise watch and the overrun window (see hil/supervisor.py WatchTuning)
    link_noise_jump_rad: float = 1.0e-4
    link_noise_window_ticks: int = 20
    link_noise_fraction: float = 0.5
    overrun_window_s: float = 1.0
    on_link_noisy: str = "hold"
    on_command_invalid: str = "hold"


@dataclass(frozen=True)
class EmulatorConfig:
    """The virtual testbed's physics and behaviour; ignored on real hardware."""

    clock: str = "lockstep"
    seed: int = 0
    plant: dict[str, Any] = field(default_factory=dict)  # TestbedPlantParams overrides
    servo: dict[str, Any] = field(default_factory=dict)  # H54ServoParams overrides
    reboot_time_s: float = 0.5


@dataclass(frozen=True)
class Config:
    loop: LoopConfig
    dynamixel: DynamixelConfig
    can: CanConfig
    joints: tuple[JointConfig, ...]
    force_sensor: ForceSensorConfig
    controller: ControllerConfig
    safety: SafetyConfig
    emulator: EmulatorConfig
    source: str = "<built-in>"

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(j.name for j in self.joints)

    def with_overrides(self, **sections: Any) -> Config:
        """A copy with whole sections replaced (e.g. dynamixel=..., can=...)."""
        return dataclasses.replace(self, **sections)


_SECTIONS: dict[str, type] = {
    "loop": LoopConfig,
    "dynamixel": DynamixelConfig,
    "can": CanConfig,
    "force_sensor": ForceSensorConfig,
    "controller": ControllerConfig,
    "safety": SafetyConfig,
    "emulator": EmulatorConfig,
}
REACTIONS = ("hold", "back_off", "torque_off")
CONTROLLER_NAMES = ("pid", "gc", "gc+lqr", "gc+lqr+dob")


def default_config_text() -> str:
    return resources.files("hil").joinpath("data", DEFAULT_CONFIG_NAME).read_text()


def load_config(path: str | Path | None = None) -> Config:
    """Read and check a configuration file; None reads the built-in testbed sample."""
    if path is None:
        return parse_config(default_config_text(), source=f"<built-in {DEFAULT_CONFIG_NAME}>")
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ConfigError(f"cannot read configuration file {path}: {exc.strerror}") from exc
    return parse_config(text, source=str(path))


def parse_config(text: str, source: str = "<string>") -> Config:
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{source}: not valid TOML: {exc}") from exc
    known = set(_SECTIONS) | {"joint"}
    unknown = sorted(set(raw) - known)
    if unknown:
        raise ConfigError(
            f"{source}: unknown section(s) {unknown}; expected some of {sorted(known)}"
        )
    sections = {
        name: _build(cls, raw.get(name, {}), f"{source} [{name}]")
        for name, cls in _SECTIONS.items()
    }
    joint_tables = raw.get("joint", [])
    if not isinstance(joint_tables, list) or not joint_tables:
        raise ConfigError(f"{source}: at least one [[joint]] table is required")
    joints = tuple(
        _build(JointConfig, table, f"{source} [[joint]] #{i + 1}")
        for i, table in enumerate(joint_tables)
    )
    config = Config(joints=joints, source=source, **sections)
    _check(config)
    return config


def _build(cls: type, table: Any, where: str) -> Any:
    if not isinstance(table, dict):
        raise ConfigError(f"{where}: expected a table, got {type(table).__name__}")
    fields = {f.name: f for f in dataclasses.fields(cls)}
    unknown = sorted(set(table) - set(fields))
    if unknown:
        raise ConfigError(f"{where}: unknown key(s) {unknown}; known keys: {sorted(fields)}")
    hints = typing.get_type_hints(cls)
    values = {}
    for name, value in table.items():
        values[name] = _coerce(value, hints[name], f"{where} {name}")
    missing = [
        name
        for name, f in fields.items()
        if name not in values
        and f.default is dataclasses.MISSING
        and f.default_factory is dataclasses.MISSING
    ]
    if missing:
        raise ConfigError(f"{where}: missing required key(s) {missing}")
    return cls(**values)


def _coerce(value: Any, hint: Any, where: str) -> Any:
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        options = [h for h in typing.get_args(hint) if h is not type(None)]
        return _coerce(value, options[0], where)
    if hint is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ConfigError(f"{where}: expected a number, got {value!r}")
        if not math.isfinite(value):
            raise ConfigError(f"{where}: expected a finite number, got {value!r}")
        return float(value)
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{where}: expected an integer, got {value!r}")
        return value
    if hint is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"{where}: expected true or false, got {value!r}")
        return value
    if hint is str:
        if not isinstance(value, str):
            raise ConfigError(f"{where}: expected a string, got {value!r}")
        return value
    if origin is dict:
        if not isinstance(value, dict):
            raise ConfigError(f"{where}: expected a table, got {value!r}")
        return dict(value)
    return value


def _check(config: Config) -> None:
    src = config.source
    if config.loop.rate_hz <= 0 or config.loop.rate_hz > 2000:
        raise ConfigError(f"{src} [loop] rate_hz: must be in (0, 2000], got {config.loop.rate_hz}")
    if config.loop.stop_cycles < 0:
        raise ConfigError(f"{src} [loop] stop_cycles: must be >= 0")
    if config.dynamixel.baudrate <= 0:
        raise ConfigError(f"{src} [dynamixel] baudrate: must be > 0")
    if config.dynamixel.model != "H54-200-S500-R":
        raise ConfigError(
            f"{src} [dynamixel] model: only 'H54-200-S500-R' is supported, got "
            f"{config.dynamixel.model!r}"
        )
    for kind, ids in (
        ("dynamixel_id", [j.dynamixel_id for j in config.joints]),
        ("encoder_node_id", [j.encoder_node_id for j in config.joints]),
        ("name", [j.name for j in config.joints]),
    ):
        duplicates = sorted({i for i in ids if ids.count(i) > 1}, key=str)
        if duplicates:
            raise ConfigError(f"{src} [[joint]]: duplicate {kind} {duplicates}")
    for joint in config.joints:
        where = f"{src} [[joint]] {joint.name!r}"
        if not 0 <= joint.dynamixel_id <= 252:
            raise ConfigError(f"{where} dynamixel_id: must be 0..252, got {joint.dynamixel_id}")
        if not 1 <= joint.encoder_node_id <= 127:
            raise ConfigError(
                f"{where} encoder_node_id: must be 1..127, got {joint.encoder_node_id}"
            )
        if joint.encoder_node_id == config.force_sensor.node_id:
            raise ConfigError(f"{where} encoder_node_id: clashes with [force_sensor] node_id")
        for key in ("encoder_direction", "motor_direction"):
            if getattr(joint, key) not in (1, -1):
                raise ConfigError(f"{where} {key}: must be 1 or -1")
        if joint.encoder_counts_per_rev <= 0:
            raise ConfigError(f"{where} encoder_counts_per_rev: must be > 0")
        if not joint.min_angle_rad < joint.max_angle_rad:
            raise ConfigError(
                f"{where}: min_angle_rad ({joint.min_angle_rad}) must be below max_angle_rad "
                f"({joint.max_angle_rad})"
            )
        for key in ("min_angle_rad", "max_angle_rad"):
            motor_angle = getattr(joint, key) * joint.motor_direction + joint.motor_offset_rad
            if abs(motor_angle) > H54_POSITION_RANGE_RAD:
                raise ConfigError(
                    f"{where} {key}: {getattr(joint, key)} rad is outside the H54's position "
                    f"range (+-{H54_POSITION_RANGE_RAD:.4f} rad after offset and direction)"
                )
        for key in (
            "stiffness_nm_per_rad",
            "servo_gain_per_s",
            "link_inertia_kg_m2",
        ):
            if getattr(joint, key) <= 0:
                raise ConfigError(f"{where} {key}: must be > 0")
        if joint.torque_limit_a is not None and not 0 < joint.torque_limit_a <= 30.0:
            raise ConfigError(f"{where} torque_limit_a: must be in (0, 30] A")
    ctrl = config.controller
    if ctrl.name not in CONTROLLER_NAMES:
        raise ConfigError(
            f"{src} [controller] name: {ctrl.name!r} is not one of {list(CONTROLLER_NAMES)}"
        )
    if ctrl.composition not in ("accumulated", "literal"):
        raise ConfigError(f"{src} [controller] composition: 'accumulated' or 'literal'")
    if ctrl.discretization not in ("euler", "zoh"):
        raise ConfigError(f"{src} [controller] discretization: 'euler' or 'zoh'")
    safety = config.safety
    for key in (
        "on_hardware_error",
        "on_deflection",
        "on_current",
        "on_link_stale",
        "on_bus_error",
        "on_overrun",
        "on_exit",
        "on_link_noisy",
        "on_command_invalid",
    ):
        if getattr(safety, key) not in REACTIONS:
            raise ConfigError(
                f"{src} [safety] {key}: {getattr(safety, key)!r} is not one of {list(REACTIONS)}"
            )
    if not (
        safety.link_noise_jump_rad > 0
        and safety.link_noise_window_ticks >= 2
        and 0 < safety.link_noise_fraction <= 1
        and safety.overrun_window_s > 0
    ):
        raise ConfigError(
            f"{src} [safety]: link_noise_jump_rad and overrun_window_s must be > 0, "
            "link_noise_window_ticks >= 2 and link_noise_fraction in (0, 1]"
        )
    for key in ("max_goal_rate_rad_s", "max_deflection_rad", "current_guard_time_s"):
        if not getattr(safety, key) > 0:
            raise ConfigError(f"{src} [safety] {key}: must be > 0")
    if not 0 < safety.current_guard_fraction <= 1:
        raise ConfigError(f"{src} [safety] current_guard_fraction: must be in (0, 1]")
    if config.force_sensor.direction not in (1, -1):
        raise ConfigError(f"{src} [force_sensor] direction: must be 1 or -1")
    if config.emulator.clock not in ("lockstep", "realtime"):
        raise ConfigError(f"{src} [emulator] clock: 'lockstep' or 'realtime'")
