"""The configuration file's sections, declared once (pydantic): types, ranges, units.

A file is split the way a robot is: the buses (`[[dynamixel]]` chains, `[[can]]` channels),
the joints (`[[joint]]`: which devices, their mounting and limits), the robot model the
controller uses (`[model]`), the controller, the safety supervisor and the emulator. Device
facts (ID ranges, baud rates, current limits, position ranges) are not repeated here: the
drivers' own configurations check them when `hil` builds the buses (`hil.wiring`).

Every number must be finite and within its physical range (`hil.config.figures` and the
comment beside each key say why it ends where it does); bools are not numbers; unknown keys are
refused. A watch of [safety] is switched off only by its documented switch, never by a huge
number.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

from pydantic import Field, field_validator, model_validator

from controller import (
    COMPOSITION_READINGS,
    LqrDesign,
    ServoModel,
)
from hil.config.control_sections import (
    ControllerSection,
    ModelSection,
    WalkingSection,
)
from hil.config.emulator_overrides import check_overrides
from hil.config.figures import Kdist, WatchTicks, WatchWindowTicks
from hil.config.section import Section
from hil.vocabulary import EmulatorClock, Reaction, SafetyCause

Direction = Literal[1, -1]
ZeroError = Annotated[float, Field(ge=-0.1, le=0.1)]
ForceOffset = Annotated[float, Field(ge=-1.0e4, le=1.0e4)]
TorqueOffset = Annotated[float, Field(ge=-1.0e3, le=1.0e3)]
# The choices the controller package defines (one definition each, in controller/).
CompositionName = Annotated[str, Field(json_schema_extra={"enum": list(COMPOSITION_READINGS)})]


class LoopSection(Section):
    # Kim et al.: "The control frequency is 200 Hz". From 10 Hz (slower, the loop no longer
    # samples the testbed's gear mode, sqrt(K / I) = 12 Hz) to 2 kHz (the RS-485 cycle alone
    # takes ~0.5 ms: docs/realtime.md).
    rate_hz: float = Field(200.0, ge=10, le=2000)
    stop_cycles: int = Field(5, ge=0, le=1000)  # hold commands at start-up and before shutdown
    # a tick's wait for the TPDOs: at least one CAN frame's time (~0.1 ms at 1 Mbit/s), and
    # below the loop's period (checked with rate_hz below): the wait is part of the tick
    bus_read_timeout_ms: float = Field(2.0, ge=0.1, le=100)
    # the wall clock sleeps to this long before a tick, then spins; a period or more: it never
    # sleeps (a core of its own busy; fewer late ticks on a virtual machine: docs/realtime.md)
    spin_before_tick_ms: float = Field(0.3, ge=0, le=1000)

    @property
    def spin_before_tick_s(self) -> float:
        return self.spin_before_tick_ms / 1000.0

    @property
    def period_s(self) -> float:
        return 1.0 / self.rate_hz


class DynamixelSection(Section):
    """One RS-485 port with a chain of actuators; `model` is its joints' model where a joint
    names none (`[[joint]] actuator`), an e-Manual name of the DYNAMIXEL PRO family."""

    name: str = Field("dynamixel", min_length=1)
    port: str = ""
    baudrate: int = Field(3_000_000, gt=0)  # one the model's Baud Rate item offers (drivers)
    model: str = "H54-200-S500-R"
    # ROBOTIS advise 1 ms on FTDI adapters; the FTDI chip's latency timer holds 1..255 ms
    latency_timer_ms: float = Field(1.0, gt=0, le=255)
    # ROBOTIS advise 0 for fast sync reads; the Return Delay Time item holds 0..254 x 2 us
    return_delay_time_us: int = Field(0, ge=0, le=508)


class CanSection(Section):
    """One CAN channel (python-can's `can.Bus(interface=..., channel=..., bitrate=...)`)."""

    name: str = Field("can", min_length=1)
    interface: str = Field("socketcan", min_length=1)
    channel: str = Field("can0", min_length=1)
    # bit/s (python-can's socketcan ignores it): classical CAN's 10 kbit/s .. 1 Mbit/s (CiA 301)
    bitrate: int = Field(1_000_000, ge=10_000, le=1_000_000)
    options: dict[str, Any] = Field(default_factory=dict)  # extra can.Bus(...) keyword args

    def bus_kwargs(self) -> dict[str, Any]:
        kwargs: dict[str, Any] = {"interface": self.interface, "channel": self.channel}
        if self.bitrate:
            kwargs["bitrate"] = self.bitrate
        kwargs.update(self.options)
        return kwargs


class ForceSensorSection(Section):
    node_id: int = Field(0, ge=0, le=127)  # 0: no force sensor
    can: str | None = None  # the channel it is on (None: the only one)
    direction: Direction = 1  # sign from its reading to a force pressing the link back
    # its reading with nothing touching (subtracted): within +-10 kN, more than any load cell
    # an H54's 48 N m current limit can load (70 N at the testbed's 0.7 m lever)
    offset_n: float = Field(0.0, ge=-1.0e4, le=1.0e4)


class ForceTorqueSensorSection(Section):
    """A six-axis force/torque sensor on CAN (the humanoid's feet: name them "left_foot" and
    "right_foot"); its readings are logged as `<name>_fx_n` ... `<name>_mz_nm`."""

    name: str = Field(min_length=1)
    node_id: int = Field(ge=1, le=127)
    can: str | None = None  # the channel it is on (None: the only one)
    # readings at zero load: within +-10 kN and +-1 kN m (a humanoid foot's six-axis sensor is
    # rated for some kN; DYROS-JET weighs ~500 N)
    # (not strict: TOML and meta.json give an array, a list in Python)
    force_offset_n: tuple[ForceOffset, ForceOffset, ForceOffset] = Field(
        (0.0, 0.0, 0.0), strict=False
    )
    torque_offset_nm: tuple[TorqueOffset, TorqueOffset, TorqueOffset] = Field(
        (0.0, 0.0, 0.0), strict=False
    )


class JointSection(Section):
    """One flexible joint: its actuator, its link encoder, their mounting and its limits."""

    name: str = Field(min_length=1)
    dynamixel_id: int
    dynamixel: str | None = None  # the chain it is on (None: the only one)
    # its actuator's model, an e-Manual name ("H54-100-S500-R", "H42-20-S300-R(A)", docs/
    # actuators.md); None: its chain's `model`. The driver checks it (and PING) at open.
    actuator: str | None = Field(None, min_length=1)
    # its link encoder's CANopen node; 0: the joint has none (a stock arm: the motor angle
    # through the gear stands for the link's, and controllers that need the link angle, the
    # LQR's, are refused)
    encoder_node_id: int  # the drivers judge it (a CANopen node ID, 1-127)
    can: str | None = None  # the CAN channel of its encoder (None: the only one)
    # None: the driver's RLC2IC figure. From 4096 (1.5 mrad a count, half the testbed's static
    # deflection m g r / K = 3.1 mrad: coarser cannot see the deflection the controller acts on)
    # to 2**31 (a CiA 406 INTEGER32 position must hold one turn).
    encoder_counts_per_rev: int | None = Field(None, ge=4096, le=2**31)
    # The offsets, limits, IDs and current limit are device facts: the drivers judge them when
    # the configuration is checked (an offset within the encoder's INTEGER32 reach, limits and
    # motor offset within the H54's position-mode range +-pi, a Torque Limit it holds).
    encoder_offset_rad: float = 0.0
    encoder_direction: Direction = 1
    motor_offset_rad: float = 0.0
    motor_direction: Direction = 1
    min_angle_rad: float = -1.0
    max_angle_rad: float = 1.0
    torque_limit_a: float | None = Field(None, gt=0)  # None: leave the device's Torque Limit
    # The servo's gain registers (device units, as the e-Manual defines them; None: the device's)
    position_p_gain: int | None = Field(None, ge=0, le=65535)
    velocity_p_gain: int | None = Field(None, ge=0, le=65535)
    velocity_i_gain: int | None = Field(None, ge=0, le=65535)

    @model_validator(mode="after")
    def _range(self) -> JointSection:
        if not self.min_angle_rad < self.max_angle_rad:
            raise ValueError(
                f"min_angle_rad ({self.min_angle_rad}) must be below max_angle_rad "
                f"({self.max_angle_rad})"
            )
        return self


def _reaction(default: Reaction) -> Any:
    return Field(default, strict=False)


class SafetySection(Section):
    """What the supervisor watches and what it does about it (README, "Safety").

    link_noise_*: the link-encoder noise watch (hil/safety/link_watches.py LinkNoiseWatch); what
        it finds is `link_noisy` (the encoder) or `oscillation` (the joint: the motor moves back
        and forth with the link), each with its reaction `on_link_noisy` / `on_oscillation`.
    overrun_window_s: missed deadlines are counted over this sliding window.
    zero_offset_margin_rad: at rest with torque off, how far the link and motor angles may
        disagree before the zero offsets are called wrong (the start gate refuses the run,
        `hil monitor` flags it). It must hold the gear's static deflection under gravity
        (m g r / K: 3.1 mrad on the paper's testbed) and its friction (~2 mrad).

    Every figure is bounded (the comment beside it says why) so that no huge number switches a
    watch off; the switches are `current_guard` (the software overload guard) and the reactions.
    """

    # the goals' rate limit: at most 3.5 rad/s, the H54-200-S500-R's no-load speed (33.1 rpm =
    # 3.47 rad/s, e-Manual): a limit beyond what the actuator can move limits nothing
    max_goal_rate_rad_s: float = Field(2.0, gt=0, le=3.5)
    # at most 0.5 rad: the H54's 44.7 N m continuous torque deflects the softest gear [model]
    # admits (100 N m/rad) by 0.45 rad; a bound beyond any deflection the joint can have
    # watches nothing
    max_deflection_rad: float = Field(0.06, gt=0, le=0.5)
    zero_offset_margin_rad: float = Field(0.01, gt=0)  # at most max_deflection_rad (below)
    current_guard: bool = True  # the guard's switch
    current_guard_fraction: float = Field(0.8, gt=0, le=1)
    # at most 1.5 s: the guard must act before the actuator's own protection, which the
    # emulated H54 trips after 1.5 s near its limit (ROBOTIS publish no figure)
    current_guard_time_s: float = Field(0.6, gt=0, le=1.5)
    # at most 0.2 rad: a back-off is a small step away from the load (400 N m at K = 2000)
    current_guard_backoff_rad: float = Field(0.05, ge=0, le=0.2)
    # set: the guard mirrors the actuator model's own overload protection and fires this long
    # before it would trip; the two keys above then do not apply (hil/safety/overload.py; below
    # the H54-200-S500-R's modelled trip time, 1.5 s)
    current_guard_margin_s: float | None = Field(None, gt=0, lt=1.5)
    link_stale_ticks: WatchTicks = 4
    bus_error_ticks: WatchTicks = 3
    # more than this many missed deadlines in overrun_window_s: below the ticks the window
    # holds (checked with [loop] rate_hz), else it could never be reached
    overrun_limit: int = Field(20, ge=0, le=20000)
    # at most 10 mrad: a link alternating by more every tick is an oscillation of the whole
    # link at the loop's rate; a bound above it finds no noisy encoder
    link_noise_jump_rad: float = Field(1.0e-4, gt=0, le=0.01)
    # a second difference needs two ticks to alternate; at most 200 ticks (1 s at 200 Hz)
    link_noise_window_ticks: int = Field(20, ge=2, le=200)
    link_noise_fraction: float = Field(0.5, gt=0, le=1)
    overrun_window_s: float = Field(1.0, gt=0, le=60)  # at most a minute
    # Legal but dangerous: a DOB gain beyond what the paper used and the closed-loop analysis
    # covers (controller/composition.py; tests/controller/test_closed_loop.py), and goals
    # clipped at the position limits on most ticks (the controller is fighting the limits).
    max_kdist: Kdist = 1.0  # at most 10 ([controller] kdist's own bound)
    goal_saturation_fraction: float = Field(0.5, gt=0, le=1)
    goal_saturation_window_ticks: WatchWindowTicks = 200
    on_hardware_error: Reaction = _reaction(Reaction.TORQUE_OFF)
    on_torque_lost: Reaction = _reaction(Reaction.TORQUE_OFF)
    on_bus_error: Reaction = _reaction(Reaction.TORQUE_OFF)
    on_link_stale: Reaction = _reaction(Reaction.HOLD)
    on_link_noisy: Reaction = _reaction(Reaction.HOLD)
    on_oscillation: Reaction = _reaction(Reaction.HOLD)
    on_deflection: Reaction = _reaction(Reaction.HOLD)
    on_current: Reaction = _reaction(Reaction.BACK_OFF)
    on_command_invalid: Reaction = _reaction(Reaction.HOLD)
    on_goal_saturated: Reaction = _reaction(Reaction.HOLD)
    on_gain_out_of_range: Reaction = _reaction(Reaction.HOLD)
    on_overrun: Reaction = _reaction(Reaction.HOLD)
    on_controller_fault: Reaction = _reaction(Reaction.TORQUE_OFF)
    on_exit: Reaction = _reaction(Reaction.TORQUE_OFF)

    def reaction(self, cause: SafetyCause) -> Reaction:
        return getattr(self, cause.config_key)

    @model_validator(mode="after")
    def _margin(self) -> SafetySection:
        if self.zero_offset_margin_rad > self.max_deflection_rad:
            raise ValueError(
                f"zero_offset_margin_rad ({self.zero_offset_margin_rad}) must not exceed "
                f"max_deflection_rad ({self.max_deflection_rad})"
            )
        return self

    @field_validator("on_exit")
    @classmethod
    def _exit(cls, value: Reaction) -> Reaction:
        if value not in (Reaction.TORQUE_OFF, Reaction.HOLD):
            raise ValueError("must be 'torque_off' or 'hold' (the torque state a run leaves)")
        return value


class EmulatorSection(Section):
    """The virtual testbed's physics and behaviour (also checked when driving hardware)."""

    clock: EmulatorClock = Field(EmulatorClock.LOCKSTEP, strict=False)
    seed: int = Field(0, ge=0, le=2**63 - 1)  # TOML's largest integer: --seed as a file holds it
    # Overrides of the emulated robot's truth, each figure within its range
    # (hil/config/emulator_overrides.py); unknown keys are refused by the emulator's own classes.
    plant: dict[str, Any] = Field(default_factory=dict)  # plant parameter overrides
    servo: dict[str, Any] = Field(default_factory=dict)  # servo parameter overrides
    sensor_noise: dict[str, Any] = Field(default_factory=dict)  # CAN sensors' noise overrides
    # at most 3 s: the drivers wait 3 s for a rebooted actuator to answer again
    # (DynamixelChainConfig.reboot_timeout_s); a longer emulated reboot never ends for them
    reboot_time_s: float = Field(0.5, gt=0, le=3.0)
    # The emulated USB-serial adapter's latency timer in realtime mode (None: the chain's
    # `latency_timer_ms`, as if set so; 16 rehearses an FTDI adapter left at its default).
    usb_latency_timer_ms: float | None = Field(None, ge=0, le=255)
    # How far the emulated devices' zeros are from the [[joint]] offsets [rad]: what the host
    # reads of a robot whose calibration is off (`hil twin` fits them): one figure for every
    # joint or one per [[joint]]; within 0.1 rad (the start gate refuses a link and motor that
    # disagree by more than [safety] zero_offset_margin_rad at rest)
    motor_zero_error_rad: ZeroError | list[ZeroError] = 0.0
    link_zero_error_rad: ZeroError | list[ZeroError] = 0.0

    def zero_errors(self, n_joints: int) -> tuple[list[float], list[float]]:
        """(motor, link) zero errors of each of n joints; ValueError if a list has another
        length."""
        out = []
        for key in ("motor_zero_error_rad", "link_zero_error_rad"):
            value = getattr(self, key)
            values = [float(v) for v in value] if isinstance(value, list) else [value] * n_joints
            if len(values) != n_joints:
                raise ValueError(
                    f"[emulator] {key}: {len(values)} figures for {n_joints} [[joint]] tables"
                )
            out.append(values)
        return out[0], out[1]

    @field_validator("plant", "servo", "sensor_noise")
    @classmethod
    def _finite(cls, value: dict[str, Any]) -> dict[str, Any]:
        _finite_numbers(value, "")
        return value

    @model_validator(mode="after")
    def _in_range(self) -> EmulatorSection:
        for part in ("plant", "servo", "sensor_noise"):
            check_overrides(part, getattr(self, part))
        return self


def _finite_numbers(value: Any, where: str) -> None:
    """Every number in a table of overrides finite (the emulator's own checks skip some: a NaN
    mass would only show once the plant runs), named by its key."""
    if isinstance(value, dict):
        for key, item in value.items():
            _finite_numbers(item, f"{where}.{key}" if where else str(key))
    elif isinstance(value, list | tuple):
        for index, item in enumerate(value):
            _finite_numbers(item, f"{where}[{index}]")
    elif isinstance(value, float) and not math.isfinite(value):
        raise ValueError(f"{where}: must be a finite number, got {value}")


class ConfigFile(Section):
    """A whole configuration file. `[dynamixel]`/`[can]` may be one table or an array of them."""

    loop: LoopSection = Field(default_factory=LoopSection)
    dynamixel: list[DynamixelSection] = Field(min_length=1)
    can: list[CanSection] = Field(min_length=1)
    force_sensor: ForceSensorSection = Field(default_factory=ForceSensorSection)
    force_torque_sensors: list[ForceTorqueSensorSection] = Field(
        default_factory=list, alias="force_torque_sensor"
    )
    joints: list[JointSection] = Field(alias="joint", min_length=1)
    model: ModelSection = Field(default_factory=ModelSection)
    controller: ControllerSection = Field(default_factory=ControllerSection)
    walking: WalkingSection = Field(default_factory=WalkingSection)
    safety: SafetySection = Field(default_factory=SafetySection)
    emulator: EmulatorSection = Field(default_factory=EmulatorSection)

    @field_validator("dynamixel", "can", mode="before")
    @classmethod
    def _one_or_many(cls, value: Any) -> Any:
        return [value] if isinstance(value, dict) else value

    @model_validator(mode="after")
    def _dob_filter_below_nyquist(self) -> ConfigFile:
        # a sampled first-order filter has no cut-off above half the sampling rate
        cutoff, nyquist = self.controller.dob_cutoff_hz, self.loop.rate_hz / 2.0
        if cutoff is not None and cutoff >= nyquist:
            raise ValueError(
                f"[controller] dob_cutoff_hz ({cutoff:g} Hz) must be below the Nyquist frequency "
                f"of [loop] rate_hz ({self.loop.rate_hz:g} Hz): {nyquist:g} Hz"
            )
        return self

    @model_validator(mode="after")
    def _watches_within_the_loop(self) -> ConfigFile:
        # figures whose range is the loop's own: a wait that outlasts the tick it is part of,
        # an overrun count the window can never reach (the watch would be off)
        period_ms = 1000.0 / self.loop.rate_hz
        if self.loop.bus_read_timeout_ms >= period_ms:
            raise ValueError(
                f"[loop] bus_read_timeout_ms ({self.loop.bus_read_timeout_ms:g} ms) must be "
                f"below the period of [loop] rate_hz ({period_ms:g} ms): the wait is part of "
                "the tick"
            )
        window_ticks = self.safety.overrun_window_s * self.loop.rate_hz
        if self.safety.overrun_limit >= window_ticks:
            raise ValueError(
                f"[safety] overrun_limit ({self.safety.overrun_limit}) must be below the ticks "
                f"overrun_window_s holds at [loop] rate_hz ({window_ticks:g}): more missed "
                "deadlines than ticks can never happen, and the watch would be off"
            )
        return self

    @model_validator(mode="after")
    def _consistent(self) -> ConfigFile:
        _unique("[[dynamixel]] name", [d.name for d in self.dynamixel])
        _unique("[[can]] name", [c.name for c in self.can])
        _unique("[[joint]] name", [j.name for j in self.joints])
        chains = {d.name for d in self.dynamixel}
        channels = {c.name for c in self.can}
        for joint in self.joints:
            _refers(f"[[joint]] {joint.name!r} dynamixel", joint.dynamixel, chains)
            _refers(f"[[joint]] {joint.name!r} can", joint.can, channels)
        _refers("[force_sensor] can", self.force_sensor.can, channels)
        _unique("[[force_torque_sensor]] name", [f.name for f in self.force_torque_sensors])
        for sensor in self.force_torque_sensors:
            _refers(f"[[force_torque_sensor]] {sensor.name!r} can", sensor.can, channels)
        for chain in chains:
            ids = [j.dynamixel_id for j in self.joints if self.chain_of(j) == chain]
            _unique(f"dynamixel_id on chain {chain!r}", ids)
        for channel in channels:
            nodes = [
                j.encoder_node_id
                for j in self.joints
                if self.channel_of(j) == channel and j.encoder_node_id
            ]
            if self.force_sensor.node_id and self.force_sensor_channel == channel:
                nodes.append(self.force_sensor.node_id)
            nodes += [f.node_id for f in self.force_torque_sensors if self.channel_of(f) == channel]
            _unique(f"CAN node ID (encoders and force sensor) on channel {channel!r}", nodes)
        unknown = sorted(set(self.model.joint) - {j.name for j in self.joints})
        if unknown:
            raise ValueError(f"[model.joint] names joints that do not exist: {unknown}")
        cascade = self.model.servo_model is ServoModel.CASCADE
        if cascade and self.controller.discretization is LqrDesign.EULER:
            raise ValueError(
                "[model] servo_model = 'cascade' with [controller] discretization = 'euler': "
                "the cascade's fast pole lies beyond forward Euler's reach at this rate; use "
                "'zoh' or 'continuous-cost'"
            )
        return self

    def chain_of(self, joint: JointSection) -> str:
        return joint.dynamixel or self.dynamixel[0].name

    @property
    def joints_without_link_encoder(self) -> tuple[str, ...]:
        """The joints with `encoder_node_id = 0` (their motor angle stands for the link's)."""
        return tuple(j.name for j in self.joints if not j.encoder_node_id)

    def actuator_of(self, joint: JointSection) -> str:
        """The joint's actuator model: its own `actuator`, else its chain's `model`."""
        chain = self.chain_of(joint)
        return joint.actuator or next(d.model for d in self.dynamixel if d.name == chain)

    def channel_of(self, device: JointSection | ForceTorqueSensorSection) -> str:
        return device.can or self.can[0].name

    @property
    def force_sensor_channel(self) -> str:
        return self.force_sensor.can or self.can[0].name


def _unique(what: str, values: list[Any]) -> None:
    duplicates = sorted({v for v in values if values.count(v) > 1}, key=str)
    if duplicates:
        raise ValueError(f"duplicate {what}: {duplicates}")


def _refers(where: str, name: str | None, names: set[str]) -> None:
    if name is None:
        if len(names) > 1:
            raise ValueError(f"{where}: required when there are several ({sorted(names)})")
    elif name not in names:
        raise ValueError(f"{where}: {name!r} is not one of {sorted(names)}")
