"""The configuration file's sections, declared once (pydantic): types, ranges, units.

A file is split the way a robot is: the buses (`[[dynamixel]]` chains, `[[can]]` channels),
the joints (`[[joint]]`: which devices, their mounting and limits), the robot model the
controller uses (`[model]`), the controller, the safety supervisor and the emulator. Device
facts (ID ranges, baud rates, current limits, position ranges) are not repeated here: the
drivers' own configurations check them when `hil` builds the buses (`hil.wiring`).

Every number must be finite; bools are not numbers; unknown keys are refused.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from controller import (
    COMPOSITION_READINGS,
    LAB_KDIST_RAMP_S,
    LINK_VELOCITY_INCREMENTS,
    LQR_DESIGNS,
)
from hil.vocabulary import ControllerKind, EmulatorClock, Reaction, SafetyCause

Direction = Literal[1, -1]
# The choices the controller package defines (one definition each, in controller/).
CompositionName = Annotated[str, Field(json_schema_extra={"enum": list(COMPOSITION_READINGS)})]


class Section(BaseModel):
    """Common rules: strict types, finite numbers, no unknown keys, immutable."""

    model_config = ConfigDict(
        extra="forbid", strict=True, allow_inf_nan=False, frozen=True, populate_by_name=True
    )


class LoopSection(Section):
    rate_hz: float = Field(200.0, gt=0, le=2000)  # Kim et al.: "The control frequency is 200 Hz"
    stop_cycles: int = Field(5, ge=0, le=1000)  # hold commands at start-up and before shutdown
    bus_read_timeout_ms: float = Field(2.0, gt=0, le=1000)  # a tick's wait for the TPDOs
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
    """One RS-485 port with a chain of actuators of one model."""

    name: str = Field("dynamixel", min_length=1)
    port: str = ""
    baudrate: int = Field(3_000_000, gt=0)
    model: str = "H54-200-S500-R"
    latency_timer_ms: float = Field(1.0, gt=0, le=1000)  # ROBOTIS advise 1 ms on FTDI adapters
    return_delay_time_us: int = Field(0, ge=0)  # ROBOTIS advise 0 for fast sync reads


class CanSection(Section):
    """One CAN channel (python-can's `can.Bus(interface=..., channel=..., bitrate=...)`)."""

    name: str = Field("can", min_length=1)
    interface: str = Field("socketcan", min_length=1)
    channel: str = Field("can0", min_length=1)
    bitrate: int = Field(1_000_000, ge=0)  # 0: leave the adapter's
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
    offset_n: float = 0.0  # its reading with nothing touching (subtracted)


class ForceTorqueSensorSection(Section):
    """A six-axis force/torque sensor on CAN (the humanoid's feet: name them "left_foot" and
    "right_foot"); its readings are logged as `<name>_fx_n` ... `<name>_mz_nm`."""

    name: str = Field(min_length=1)
    node_id: int = Field(ge=1, le=127)
    can: str | None = None  # the channel it is on (None: the only one)
    force_offset_n: tuple[float, float, float] = (0.0, 0.0, 0.0)  # readings at zero load
    torque_offset_nm: tuple[float, float, float] = (0.0, 0.0, 0.0)


class JointSection(Section):
    """One flexible joint: its actuator, its link encoder, their mounting and its limits."""

    name: str = Field(min_length=1)
    dynamixel_id: int
    dynamixel: str | None = None  # the chain it is on (None: the only one)
    encoder_node_id: int
    can: str | None = None  # the CAN channel of its encoder (None: the only one)
    encoder_counts_per_rev: int | None = Field(None, gt=0)  # None: the driver's RLC2IC figure
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


class JointModelSection(Section):
    """Per-joint overrides of the model's gear and servo figures."""

    stiffness_nm_per_rad: float | None = Field(None, gt=0)
    damping_nms_per_rad: float | None = Field(None, ge=0)
    servo_gain_per_s: float | None = Field(None, gt=0)
    servo_velocity_gain_nms_per_rad: float | None = Field(None, gt=0)
    rotor_inertia_kg_m2: float | None = Field(None, gt=0)
    motor_viscous_friction_nms_per_rad: float | None = Field(None, ge=0)


class ModelSection(Section):
    """The controller's (nominal) model of the robot: Kim et al. Sec. IV-A.

    robot "single_link": every joint drives its own link swinging in a vertical plane
    (the 1-DoF testbed): Sm = 1 / link_inertia_kg_m2, gravity torque m g r cos(angle).
    robot "dyros-jet": the humanoid's 12 leg joints, the whole robot from `description` (a URDF:
    a path, or the name of one shipped in hil/data/robots/): the gravity compensator (5)-(8)
    and the contact-projected Sm of (19), the LQR rescheduled every `gain_reschedule_period_s`
    off the 200 Hz path; `sm_coupling` "diagonal" (the lab's: one design per joint on Sm's
    diagonal), "full" (one design on the whole Sm; none exists in double support, where Sm is
    singular) or "closed-chain" (the whole Sm, designed on the motions the legs and the ground
    allow: controller/closed_chain.py; docs/studies/lqr_standing/ says why).
    `sm_contact`: which soles Sm holds on the ground: "both-feet" (both in double support) or
    "support-foot" (Kim et al. Sec. III-C: one foot, the other from the middle of each double
    support; `sm_standing_foot` when a run never leaves double support);
    controller/humanoid/support.py. It is not the gravity compensator's weight split.
    `servo_model`: the LQR's model of the actuator: "first-order" (the paper's (4) with
    servo_gain_per_s) or "cascade" (its position gain servo_gain_per_s, velocity loop
    servo_velocity_gain_nms_per_rad on the rotor's reflected inertia rotor_inertia_kg_m2, with
    motor_viscous_friction_nms_per_rad: controller/servo_cascade.py; needs [controller]
    discretization "zoh" or "continuous-cost").
    Gear and servo figures apply to every joint unless `[model.joint.NAME]` overrides them.
    """

    robot: Literal["single_link", "dyros-jet"] = "single_link"
    description: str | None = None
    sm_coupling: Literal["diagonal", "full", "closed-chain"] = "diagonal"
    gain_reschedule_period_s: float = Field(0.1, gt=0)  # the lab's background thread: 100 ms
    sm_contact: Literal["both-feet", "support-foot"] = "both-feet"
    sm_standing_foot: Literal["left", "right"] = "left"
    servo_model: Literal["first-order", "cascade"] = "first-order"
    stiffness_nm_per_rad: float = Field(2000.0, gt=0)
    damping_nms_per_rad: float = Field(100.0, ge=0)
    servo_gain_per_s: float = Field(10.0, gt=0)
    servo_velocity_gain_nms_per_rad: float = Field(78.5, gt=0)  # the H54: 2 pi 50 Hz x J
    rotor_inertia_kg_m2: float = Field(0.25, gt=0)  # reflected to the output
    motor_viscous_friction_nms_per_rad: float = Field(1.14, ge=0)
    link_inertia_kg_m2: float = Field(0.376, gt=0)
    gravity_moment_kg_m: float = Field(0.63, ge=0)
    joint: dict[str, JointModelSection] = Field(default_factory=dict)

    def joint_figure(self, joint: str, key: str) -> float:
        override = self.joint.get(joint)
        value = getattr(override, key) if override is not None else None
        return float(value if value is not None else getattr(self, key))


class ControllerSection(Section):
    """The controller (Kim et al. Sec. III) and its options; controller/controllers.py
    ControllerParams says what each does. The choices are the controller package's own."""

    name: ControllerKind = Field(ControllerKind.GC_LQR_DOB, strict=False)
    kdist: float = Field(1.0, ge=0)
    kdist_ramp_s: float = Field(LAB_KDIST_RAMP_S, ge=0)  # a Kdist change ramps this long
    q_error: float = Field(10.0, gt=0)  # Kim et al.: Q = 10 I, R = I
    q_state: float = Field(1.0, ge=0)
    r_input: float = Field(1.0, gt=0)
    dob_cutoff_hz: float | None = Field(None, gt=0)  # the Q filter by its cut-off, or ...
    dob_filter_pole: float | None = Field(None, ge=0, lt=1)  # ... by its pole; neither: 0.7
    composition: str = "accumulated"  # the reading of (25)
    dob_integral_time_s: float | None = Field(None, gt=0)  # "accumulated-integral" needs it
    discretization: str = "euler"  # the LQR design
    kdist_reference: Literal["per-tick", "paper-yield"] = "per-tick"  # what Kdist yields against
    reference_feedforward: bool = False  # the LQR's uc moves with the reference's increments
    link_velocity_increment: str = "backward-difference"

    @field_validator("composition")
    @classmethod
    def _composition(cls, value: str) -> str:
        return _one_of(value, COMPOSITION_READINGS)

    @field_validator("discretization")
    @classmethod
    def _discretization(cls, value: str) -> str:
        return _one_of(value, LQR_DESIGNS)

    @field_validator("link_velocity_increment")
    @classmethod
    def _increment(cls, value: str) -> str:
        return _one_of(value, LINK_VELOCITY_INCREMENTS)

    @model_validator(mode="after")
    def _filter_and_reading(self) -> ControllerSection:
        if self.dob_cutoff_hz is not None and self.dob_filter_pole is not None:
            raise ValueError("give dob_cutoff_hz or dob_filter_pole, not both")
        if self.composition == "accumulated-integral" and self.dob_integral_time_s is None:
            raise ValueError(
                "composition 'accumulated-integral' needs dob_integral_time_s (the servo's "
                "velocity-loop integral time; `hil identify` measures it)"
            )
        return self


def _one_of(value: str, choices: tuple[str, ...]) -> str:
    if value not in choices:
        raise ValueError(f"must be one of {list(choices)}")
    return value


def _reaction(default: Reaction) -> Any:
    return Field(default, strict=False)


class SafetySection(Section):
    """What the supervisor watches and what it does about it (README, "Safety").

    link_noise_*: the link-encoder noise watch (hil/safety/watches.py LinkNoiseWatch).
    overrun_window_s: missed deadlines are counted over this sliding window.
    zero_offset_margin_rad: at rest with torque off, how far the link and motor angles may
        disagree before the zero offsets are called wrong (the start gate refuses the run,
        `hil monitor` flags it). It must hold the gear's static deflection under gravity
        (m g r / K: 3.1 mrad on the paper's testbed) and its friction (~2 mrad).
    """

    max_goal_rate_rad_s: float = Field(2.0, gt=0)
    max_deflection_rad: float = Field(0.06, gt=0)
    zero_offset_margin_rad: float = Field(0.01, gt=0)
    current_guard: bool = True
    current_guard_fraction: float = Field(0.8, gt=0, le=1)
    current_guard_time_s: float = Field(0.6, gt=0)
    current_guard_backoff_rad: float = Field(0.05, ge=0)
    link_stale_ticks: int = Field(4, ge=1)
    bus_error_ticks: int = Field(3, ge=1)
    overrun_limit: int = Field(20, ge=0)
    link_noise_jump_rad: float = Field(1.0e-4, gt=0)
    link_noise_window_ticks: int = Field(20, ge=2)
    link_noise_fraction: float = Field(0.5, gt=0, le=1)
    overrun_window_s: float = Field(1.0, gt=0)
    # Legal but dangerous: a DOB gain beyond what the paper used and the closed-loop analysis
    # covers (controller/composition.py; tests/controller/test_closed_loop.py), and goals
    # clipped at the position limits on most ticks (the controller is fighting the limits).
    max_kdist: float = Field(1.0, ge=0)
    goal_saturation_fraction: float = Field(0.5, gt=0, le=1)
    goal_saturation_window_ticks: int = Field(200, ge=1)
    on_hardware_error: Reaction = _reaction(Reaction.TORQUE_OFF)
    on_torque_lost: Reaction = _reaction(Reaction.TORQUE_OFF)
    on_bus_error: Reaction = _reaction(Reaction.TORQUE_OFF)
    on_link_stale: Reaction = _reaction(Reaction.HOLD)
    on_link_noisy: Reaction = _reaction(Reaction.HOLD)
    on_deflection: Reaction = _reaction(Reaction.HOLD)
    on_current: Reaction = _reaction(Reaction.BACK_OFF)
    on_command_invalid: Reaction = _reaction(Reaction.HOLD)
    on_goal_saturated: Reaction = _reaction(Reaction.HOLD)
    on_gain_out_of_range: Reaction = _reaction(Reaction.HOLD)
    on_overrun: Reaction = _reaction(Reaction.HOLD)
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
        if value is Reaction.BACK_OFF:
            raise ValueError("must be 'torque_off' or 'hold' (the torque state a run leaves)")
        return value


class EmulatorSection(Section):
    """The virtual testbed's physics and behaviour (also checked when driving hardware)."""

    clock: EmulatorClock = Field(EmulatorClock.LOCKSTEP, strict=False)
    seed: int = Field(0, ge=0)
    plant: dict[str, Any] = Field(default_factory=dict)  # plant parameter overrides
    servo: dict[str, Any] = Field(default_factory=dict)  # servo parameter overrides
    sensor_noise: dict[str, Any] = Field(default_factory=dict)  # CAN sensors' noise overrides
    reboot_time_s: float = Field(0.5, gt=0)
    # The emulated USB-serial adapter's latency timer in realtime mode (None: the chain's
    # `latency_timer_ms`, as if set so; 16 rehearses an FTDI adapter left at its default).
    usb_latency_timer_ms: float | None = Field(None, ge=0, le=255)


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
    safety: SafetySection = Field(default_factory=SafetySection)
    emulator: EmulatorSection = Field(default_factory=EmulatorSection)

    @field_validator("dynamixel", "can", mode="before")
    @classmethod
    def _one_or_many(cls, value: Any) -> Any:
        return [value] if isinstance(value, dict) else value

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
        if self.model.robot == "dyros-jet" and self.model.description is None:
            raise ValueError("[model] description: the robot 'dyros-jet' needs its URDF")
        for chain in chains:
            ids = [j.dynamixel_id for j in self.joints if self.chain_of(j) == chain]
            _unique(f"dynamixel_id on chain {chain!r}", ids)
        for channel in channels:
            nodes = [j.encoder_node_id for j in self.joints if self.channel_of(j) == channel]
            if self.force_sensor.node_id and self.force_sensor_channel == channel:
                nodes.append(self.force_sensor.node_id)
            nodes += [f.node_id for f in self.force_torque_sensors if self.channel_of(f) == channel]
            _unique(f"CAN node ID (encoders and force sensor) on channel {channel!r}", nodes)
        unknown = sorted(set(self.model.joint) - {j.name for j in self.joints})
        if unknown:
            raise ValueError(f"[model.joint] names joints that do not exist: {unknown}")
        if self.model.servo_model == "cascade" and self.controller.discretization == "euler":
            raise ValueError(
                "[model] servo_model = 'cascade' with [controller] discretization = 'euler': "
                "the cascade's fast pole lies beyond forward Euler's reach at this rate; use "
                "'zoh' or 'continuous-cost'"
            )
        return self

    def chain_of(self, joint: JointSection) -> str:
        return joint.dynamixel or self.dynamixel[0].name

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
