"""What an identification returns, and how it is written: a JSON dict and a TOML fragment."""

from __future__ import annotations

import enum
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hil.identify.records import JointLog, KnownJointFigures


class Parameter(enum.Enum):
    """Every figure the identification reports; the value is its JSON key."""

    GEAR_STIFFNESS = "gear_stiffness_nm_per_rad"
    GEAR_DAMPING = "gear_damping_nm_s_per_rad"
    DEFLECTION_OFFSET = "gear_deflection_offset_rad"
    SERVO_KP = "servo_kp_per_s"
    POSITION_GAIN = "servo_position_gain_per_s"
    VELOCITY_GAIN = "servo_velocity_gain_nm_s_per_rad"
    VELOCITY_INTEGRAL_TIME = "servo_velocity_integral_time_s"
    CURRENT_LIMIT = "servo_current_limit_a"
    INTEGRAL_INITIAL = "servo_integral_initial_nm"
    MOTOR_INERTIA = "motor_reflected_inertia_kg_m2"
    MOTOR_VISCOUS_FRICTION = "motor_viscous_friction_nm_s_per_rad"
    MOTOR_COULOMB_FRICTION = "motor_coulomb_friction_nm"

    @property
    def unit(self) -> str:
        return _UNITS[self]


_UNITS = {
    Parameter.GEAR_STIFFNESS: "N m/rad",
    Parameter.GEAR_DAMPING: "N m s/rad",
    Parameter.DEFLECTION_OFFSET: "rad",
    Parameter.SERVO_KP: "1/s",
    Parameter.POSITION_GAIN: "1/s",
    Parameter.VELOCITY_GAIN: "N m s/rad",
    Parameter.VELOCITY_INTEGRAL_TIME: "s",
    Parameter.CURRENT_LIMIT: "A",
    Parameter.INTEGRAL_INITIAL: "N m",
    Parameter.MOTOR_INERTIA: "kg m^2",
    Parameter.MOTOR_VISCOUS_FRICTION: "N m s/rad",
    Parameter.MOTOR_COULOMB_FRICTION: "N m",
}

# The key the configuration file uses for the damping; written as an alias.
GEAR_DAMPING_CONFIG_KEY = "gear_damping_nms_per_rad"


class Status(enum.Enum):
    """How a figure was obtained."""

    IDENTIFIED = "identified"  # value with a 95 % interval from the data
    NUISANCE = "nuisance"  # fitted so the model can follow the data; not for use elsewhere
    LOWER_BOUND = "lower bound"  # the data only say it is at least `low`
    GIVEN = "given"  # told, not identified (e.g. the device's register)


@dataclass(frozen=True)
class ParameterEstimate:
    """value and its interval [low, high] (NaN/inf where the data do not bound it)."""

    value: float
    low: float
    high: float
    status: Status
    note: str = ""

    def as_json(self, unit: str) -> dict[str, Any]:
        return {
            "value": _json_number(self.value),
            "low": _json_number(self.low),
            "high": _json_number(self.high),
            "unit": unit,
            "status": self.status.value,
            **({"note": self.note} if self.note else {}),
        }


@dataclass(frozen=True)
class FitQuality:
    """How well a model reproduces one measured signal on the samples held out of the fit.

    vaf_percent: variance accounted for, 100 (1 - var(measured - model) / var(measured)).
    nrmse_percent: rms(measured - model) / rms(measured - mean(measured)), in percent.
    """

    model: str
    signal: str
    vaf_percent: float
    nrmse_percent: float
    samples: int

    def as_json(self) -> dict[str, Any]:
        return {
            "model": self.model,
            "signal": self.signal,
            "vaf_percent": _json_number(self.vaf_percent),
            "nrmse_percent": _json_number(self.nrmse_percent),
            "samples": self.samples,
        }


def fit_quality(model: str, signal: str, measured: np.ndarray, modelled: np.ndarray) -> FitQuality:
    error = measured - modelled
    spread = float(np.var(measured))
    if spread <= 0:
        return FitQuality(model, signal, math.nan, math.nan, len(measured))
    vaf = 100.0 * (1.0 - float(np.var(error)) / spread)
    nrmse = 100.0 * math.sqrt(float(np.mean(error**2)) / spread)
    return FitQuality(model, signal, vaf, nrmse, len(measured))


@dataclass(frozen=True)
class SignalTraces:
    """Measured and modelled signals of one log, for the figure (not serialised)."""

    log: JointLog
    holdout_start_index: int
    motor_angle_sim_rad: np.ndarray  # whole-joint free-run simulation
    link_angle_sim_rad: np.ndarray
    motor_current_sim_a: np.ndarray
    deflection_from_motor_rad: np.ndarray  # the link model driven by the measured motor
    first_order_motor_rad: np.ndarray  # (4) on the high-passed goal (paper's model)
    first_order_measured_rad: np.ndarray  # the high-passed measured motor angle


@dataclass(frozen=True)
class IdentificationResult:
    parameters: Mapping[Parameter, ParameterEstimate]
    quality: tuple[FitQuality, ...]
    known: KnownJointFigures
    sources: tuple[str, ...]
    notes: tuple[str, ...] = ()
    traces: tuple[SignalTraces, ...] = field(default=(), repr=False, compare=False)

    def __getitem__(self, parameter: Parameter) -> ParameterEstimate:
        return self.parameters[parameter]


def result_to_json(result: IdentificationResult) -> dict[str, Any]:
    """The JSON object `hil identify --json` prints: one key per figure, each with value, low,
    high (95 %), unit and status; then fit quality, the figures given, the logs, notes."""
    out: dict[str, Any] = {}
    for parameter, estimate in result.parameters.items():
        out[parameter.value] = estimate.as_json(parameter.unit)
        if parameter is Parameter.GEAR_DAMPING:
            out[GEAR_DAMPING_CONFIG_KEY] = out[parameter.value]
    out["fit_quality"] = [q.as_json() for q in result.quality]
    known = result.known
    out["given"] = {
        "link_inertia_kg_m2": known.link_inertia_kg_m2,
        "gravity_moment_kg_m": known.gravity_moment_kg_m,
        "torque_constant_nm_per_a": known.torque_constant_nm_per_a,
        "gravity_m_s2": known.gravity_m_s2,
        "current_limit_a": known.current_limit_a,
        "velocity_limit_rad_s": known.velocity_limit_rad_s,
    }
    out["logs"] = list(result.sources)
    out["notes"] = list(result.notes)
    return out


def _json_number(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def _fmt(value: float) -> str:
    return f"{value:.6g}"


def _interval_comment(estimate: ParameterEstimate) -> str:
    if estimate.status is Status.LOWER_BOUND:
        return f"at least {_fmt(estimate.low)} (not reached in the run)"
    if estimate.status is Status.GIVEN:
        return "given, not identified"
    return f"95 % interval {_fmt(estimate.low)} .. {_fmt(estimate.high)}"


def render_config_fragment(result: IdentificationResult, joint_name: str = "") -> str:
    """TOML the user pastes: the controller's model of the joint, and the emulator's figures.

    The first table is the joint's model in hil's configuration (`[model.joint.NAME]`, or
    `[model]` without a joint name: the figures of every joint): K, D, Kp of (1), (4) and the
    servo's cascade (position gain, velocity gain, integral time), the second an [emulator]
    table whose plant/servo overrides make the emulated testbed behave like the identified
    joint (merge its keys into an existing [emulator] table: TOML allows a table once).
    """
    p = result.parameters
    stiffness = p[Parameter.GEAR_STIFFNESS]
    damping = p[Parameter.GEAR_DAMPING]
    servo_kp = p[Parameter.SERVO_KP]
    position = p[Parameter.POSITION_GAIN]
    velocity = p[Parameter.VELOCITY_GAIN]
    integral = p[Parameter.VELOCITY_INTEGRAL_TIME]
    current = p[Parameter.CURRENT_LIMIT]
    table = f"[model.joint.{joint_name}]" if joint_name else "[model]"
    lines = [
        f"# Identified by `hil identify` from {', '.join(result.sources)}.",
        "# The controller's model of the joint (Kim et al. (1), (4)):",
        table,
        f"stiffness_nm_per_rad = {_fmt(stiffness.value)}  # {_interval_comment(stiffness)}",
        f"damping_nms_per_rad = {_fmt(damping.value)}  # {_interval_comment(damping)}",
        f"servo_gain_per_s = {_fmt(servo_kp.value)}  # (4): {_interval_comment(servo_kp)}",
        "# the servo's cascade (the gravity compensator's joint compliance 1/K + 1/(Kpp kv)):",
        f"position_gain_per_s = {_fmt(position.value)}",
        f"velocity_gain_nms_per_rad = {_fmt(velocity.value)}",
        f"velocity_integral_time_s = {_fmt(integral.value)}",
        "",
        "# The emulator made to match (overrides of sim_backend's plant and servo figures):",
        "[emulator]",
        "plant = { "
        f"gear_stiffness_nm_per_rad = {_fmt(stiffness.value)}, "
        f"gear_damping_nms_per_rad = {_fmt(damping.value)} }}",
        "servo = { "
        f"position_gain_per_s = {_fmt(position.value)}, "
        f"velocity_gain_nms_per_rad = {_fmt(velocity.value)}, "
        f"velocity_integral_time_s = {_fmt(integral.value)} }}",
        f"# position gain: {_interval_comment(position)}",
        f"# velocity gain: {_interval_comment(velocity)}",
        f"# velocity integral time: {_interval_comment(integral)}",
        f"# current limit [A]: {_interval_comment(current)}"
        + ("" if not math.isfinite(current.value) else f"; value {_fmt(current.value)}"),
        "# (the current limit is the actuator's Torque Limit register, not an emulator figure)",
    ]
    return "\n".join(lines) + "\n"
