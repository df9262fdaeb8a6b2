"""The estimators: three least-squares fits, one per part of the joint (package docstring).

1. The gear, K, D and the deflection offset: output error of the link angle simulated from
   the measured motor motion (`models.link_response`).
2. The paper's first-order servo (4), Kp: output error of the motor angle simulated from the
   goal, both high-passed alike (the first-order model has no gravity: its slow position lag,
   which the weak integral winds out, would otherwise be read as lag).
3. The actuator's cascade, Kpp, kv, Ti (and the motor side it needs): prediction error over one
   loop period from each measured state (`models.advance`), on the motor angle, velocity and
   current; K and D from fit 1.
Each fit uses the samples before the hold-out point; the rest measure the fit quality.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
import scipy.optimize
import scipy.signal
import scipy.stats

from hil.identify.covariance import sandwich_covariance
from hil.identify.models import (
    GearParams,
    JointState,
    MotorParams,
    ServoParams,
    advance,
    first_order_response,
    goal_integral,
    integral_from_log,
    link_response,
    link_velocity_estimate,
    simulate_joint,
)
from hil.identify.records import MIN_SAMPLES, JointLog, KnownJointFigures, LogFormatError
from hil.identify.result import (
    FitQuality,
    IdentificationResult,
    Parameter,
    ParameterEstimate,
    SignalTraces,
    Status,
    fit_quality,
)


@dataclass(frozen=True)
class IdentificationOptions:
    """How to fit.

    holdout_fraction: the last part of each log kept out of the fits to measure their quality.
    validation_start_s: if given, the log time (time_s) from which samples are held out
      instead (e.g. where the excitation's validation sweep begins).
    physics_step_s: the step of the cascade model inside each loop period.
    first_order_highpass_hz: corner of the high-pass applied to goal and motor angle for (4).
    confidence: level of the intervals.
    reweighting_rounds: fits of the cascade, each weighting its channels by the last residuals.
    """

    holdout_fraction: float = 0.25
    validation_start_s: float | None = None
    physics_step_s: float = 0.001
    first_order_highpass_hz: float = 0.1
    confidence: float = 0.95
    reweighting_rounds: int = 2

    def __post_init__(self) -> None:
        if not 0.0 <= self.holdout_fraction < 0.9:
            raise ValueError("holdout_fraction must be in [0, 0.9)")
        if not (self.physics_step_s > 0 and self.first_order_highpass_hz > 0):
            raise ValueError("physics_step_s and first_order_highpass_hz must be > 0")
        if not 0 < self.confidence < 1:
            raise ValueError("confidence must be in (0, 1)")
        if self.reweighting_rounds < 1:
            raise ValueError("reweighting_rounds must be >= 1")


# ----------------------------------------------------------------------------- generic fit


class _Scale(enum.Enum):
    LOG = "log"  # a positive figure, fitted as its logarithm (intervals stay positive)
    LINEAR = "linear"


@dataclass(frozen=True)
class _Coordinate:
    scale: _Scale
    step: float  # central-difference step in fit coordinates
    lower: float = -math.inf  # bounds in natural units (LINEAR only)
    upper: float = math.inf


def _to_fit(values: np.ndarray, coords: Sequence[_Coordinate]) -> np.ndarray:
    return np.array(
        [math.log(v) if c.scale is _Scale.LOG else v for v, c in zip(values, coords, strict=True)]
    )


def _from_fit(x: np.ndarray, coords: Sequence[_Coordinate]) -> np.ndarray:
    return np.array(
        [math.exp(v) if c.scale is _Scale.LOG else v for v, c in zip(x, coords, strict=True)]
    )


@dataclass(frozen=True)
class _FitOutcome:
    values: np.ndarray
    low: np.ndarray
    high: np.ndarray
    residuals: list[np.ndarray]


Blocks = Callable[[np.ndarray], list[np.ndarray]]


def _least_squares(
    blocks: Blocks, initial: np.ndarray, coords: Sequence[_Coordinate], confidence: float
) -> _FitOutcome:
    """Minimise the sum of squares of all blocks (each (N_i, C)) over the parameters.

    Returns the optimum with intervals from the sandwich covariance (covariance.py) in the
    fit coordinates, mapped back to natural units.
    """
    lower = np.array([c.lower if c.scale is _Scale.LINEAR else -np.inf for c in coords])
    upper = np.array([c.upper if c.scale is _Scale.LINEAR else np.inf for c in coords])
    x0 = np.clip(_to_fit(np.asarray(initial, dtype=float), coords), lower, upper)

    def flat(x: np.ndarray) -> np.ndarray:
        return np.concatenate([b.ravel() for b in blocks(_from_fit(x, coords))])

    solution = scipy.optimize.least_squares(
        flat, x0, bounds=(lower, upper), x_scale="jac", method="trf", xtol=1e-10, ftol=1e-10
    )
    x = solution.x
    at_optimum = blocks(_from_fit(x, coords))
    jacobians = [np.empty((*b.shape, len(x))) for b in at_optimum]
    for j, coord in enumerate(coords):
        up, down = x.copy(), x.copy()
        up[j] = min(x[j] + coord.step, upper[j])
        down[j] = max(x[j] - coord.step, lower[j])
        plus, minus = blocks(_from_fit(up, coords)), blocks(_from_fit(down, coords))
        for jac, bp, bm in zip(jacobians, plus, minus, strict=True):
            jac[..., j] = (bp - bm) / (up[j] - down[j])
    covariance = sandwich_covariance(jacobians, at_optimum)
    z = scipy.stats.norm.ppf(0.5 + confidence / 2)
    half = z * np.sqrt(np.maximum(np.diag(covariance), 0.0))
    low = _from_fit(np.maximum(x - half, lower), coords)
    high = _from_fit(np.minimum(x + half, upper), coords)
    return _FitOutcome(_from_fit(x, coords), low, high, at_optimum)


def _split_index(log: JointLog, options: IdentificationOptions) -> int:
    """First held-out sample of a log (len(log) if nothing is held out)."""
    if options.validation_start_s is not None:
        split = int(np.searchsorted(log.time_s, options.validation_start_s))
    else:
        split = int(round((1.0 - options.holdout_fraction) * len(log)))
    return min(max(split, 2), len(log))


# ----------------------------------------------------------------------------- 1. the gear


def _gear_initial_guess(logs: Sequence[JointLog], known: KnownJointFigures) -> np.ndarray:
    """Equation error of the link's equation with differentiated encoders (a starting point):
    I theta_j'' + g m r cos theta_j = K (theta_m - theta_j) + D (omega_m - theta_j') + K delta_0.
    """
    rows, targets = [], []
    for log in logs:
        period = log.period_s
        angle = log.link_angle_rad
        acceleration = (angle[2:] - 2 * angle[1:-1] + angle[:-2]) / period**2
        velocity = link_velocity_estimate(log)[1:-1]
        inner = slice(1, -1)
        targets.append(
            known.link_inertia_kg_m2 * acceleration + known.gravity_torque_nm * np.cos(angle[inner])
        )
        rows.append(
            np.column_stack(
                [
                    log.motor_angle_rad[inner] - angle[inner],
                    log.motor_velocity_rad_s[inner] - velocity,
                    np.ones(len(velocity)),
                ]
            )
        )
    coef, *_ = np.linalg.lstsq(np.vstack(rows), np.concatenate(targets), rcond=None)
    stiffness = coef[0] if coef[0] > 0 else 2000.0
    damping = coef[1] if coef[1] > 0 else 0.05 * stiffness
    return np.array([stiffness, damping, coef[2] / stiffness])


def fit_gear(
    logs: Sequence[JointLog], known: KnownJointFigures, options: IdentificationOptions
) -> tuple[GearParams, _FitOutcome]:
    """K, D and the deflection offset from the link angle (output error, measured motor in)."""
    splits = [_split_index(log, options) for log in logs]
    scale = 1e-5  # rad: residuals near one count of the link encoder

    def blocks(values: np.ndarray) -> list[np.ndarray]:
        gear = GearParams(*values)
        out = []
        for log, split in zip(logs, splits, strict=True):
            link = link_response(log, gear, known)
            out.append(((link.angle_rad - log.link_angle_rad)[1:split] / scale)[:, None])
        return out

    coords = (
        _Coordinate(_Scale.LOG, 1e-4),
        _Coordinate(_Scale.LOG, 1e-4),
        _Coordinate(_Scale.LINEAR, 1e-7),
    )
    outcome = _least_squares(blocks, _gear_initial_guess(logs, known), coords, options.confidence)
    return GearParams(*outcome.values), outcome


# ----------------------------------------------------------------------------- 2. servo (4)


def _high_pass(log: JointLog, corner_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Goal and motor angle through the same 2nd-order Butterworth high-pass, from rest."""
    b, a = scipy.signal.butter(2, corner_hz, btype="highpass", fs=1.0 / log.period_s)
    goal = scipy.signal.lfilter(b, a, log.goal_rad - log.goal_rad[0])
    motor = scipy.signal.lfilter(b, a, log.motor_angle_rad - log.motor_angle_rad[0])
    return goal, motor


def fit_first_order_servo(
    logs: Sequence[JointLog], options: IdentificationOptions
) -> tuple[float, _FitOutcome]:
    """Kp of (4): the motor angle simulated from the goal, both high-passed (output error).

    The high-pass commutes with the linear model (4), so the fit is that of (4) itself on the
    band the excitation covers, without the slow gravity lag the model does not have. Both
    filters start from rest: the log must start with the motor at rest on its goal (as a run
    does, holding where torque came on).
    """
    splits = [_split_index(log, options) for log in logs]
    filtered = [_high_pass(log, options.first_order_highpass_hz) for log in logs]
    scale = 1e-4

    def blocks(values: np.ndarray) -> list[np.ndarray]:
        out = []
        for log, split, (goal, motor) in zip(logs, splits, filtered, strict=True):
            model = first_order_response(goal, motor[0], values[0], log.period_s)
            out.append(((model - motor)[1:split] / scale)[:, None])
        return out

    # Starting point: theta_m' = Kp (u - theta_m) by least squares on the filtered signals.
    num = den = 0.0
    for log, (goal, motor) in zip(logs, filtered, strict=True):
        rate = np.diff(motor) / log.period_s
        error = goal[:-1] - motor[:-1]
        num += float(rate @ error)
        den += float(error @ error)
    initial = num / den if den > 0 and num > 0 else 10.0
    outcome = _least_squares(
        blocks, np.array([initial]), (_Coordinate(_Scale.LOG, 1e-4),), options.confidence
    )
    return float(outcome.values[0]), outcome


# ----------------------------------------------------------------------------- 3. the cascade


@dataclass(frozen=True)
class _CascadeData:
    """What the one-period predictions start from: the measured state at every sample."""

    log: JointLog
    split: int
    link_velocity: np.ndarray


def _cascade_initial_guess(
    logs: Sequence[JointLog], gear: GearParams, known: KnownJointFigures
) -> np.ndarray:
    """Starting point from two linear regressions (equation error):
    Kt i = kv Kpp e - kv omega + kv/Ti (Kpp E - (theta_m - theta_m0)) + iota_0   (the servo law)
    Kt i - tau_j = Jm omega' + b omega + F_c sgn(omega)                         (the motor)
    """
    servo_rows, servo_targets, motor_rows, motor_targets = [], [], [], []
    kt = known.torque_constant_nm_per_a
    for log in logs:
        theta, omega = log.motor_angle_rad, log.motor_velocity_rad_s
        torque = kt * log.motor_current_a
        error = log.goal_rad[:-1] - theta[1:]  # the goal in force when the current was measured
        servo_rows.append(
            np.column_stack(
                [
                    error,
                    omega[1:],
                    goal_integral(log)[1:],
                    theta[1:] - theta[0],
                    np.ones(len(error)),
                ]
            )
        )
        servo_targets.append(torque[1:])
        velocity = link_velocity_estimate(log)
        gear_torque = gear.stiffness_nm_per_rad * (
            theta - log.link_angle_rad + gear.deflection_offset_rad
        ) + gear.damping_nms_per_rad * (omega - velocity)
        acceleration = np.gradient(omega, log.period_s)
        moving = np.abs(omega) > 0.05
        motor_rows.append(np.column_stack([acceleration, omega, np.sign(omega)])[moving])
        motor_targets.append((torque - gear_torque)[moving])
    beta, *_ = np.linalg.lstsq(np.vstack(servo_rows), np.concatenate(servo_targets), rcond=None)
    kv = -beta[1]
    kpp = beta[0] / kv if kv > 0 else math.nan
    integral_rate = -beta[3]
    ti = kv / integral_rate if integral_rate > 0 else math.nan
    if not (kv > 0 and kpp > 0 and math.isfinite(ti) and ti > 0):
        kpp, kv, ti = 10.0, 80.0, 15.0
    inertia, viscous, coulomb = 0.1 * known.link_inertia_kg_m2, 0.0, 0.0
    if motor_rows and sum(len(r) for r in motor_rows) > 10:
        gamma, *_ = np.linalg.lstsq(
            np.vstack(motor_rows), np.concatenate(motor_targets), rcond=None
        )
        inertia = gamma[0] if gamma[0] > 0 else inertia
        viscous, coulomb = max(gamma[1], 0.0), max(gamma[2], 0.0)
    return np.array([kpp, kv, ti, beta[4], inertia, viscous, coulomb])


def _split_cascade(values: np.ndarray) -> tuple[ServoParams, MotorParams]:
    kpp, kv, ti, integral0, inertia, viscous, coulomb = values
    return ServoParams(kpp, kv, ti, integral0), MotorParams(inertia, viscous, coulomb)


def _one_period_predictions(
    data: _CascadeData,
    gear: GearParams,
    servo: ServoParams,
    motor: MotorParams,
    known: KnownJointFigures,
    physics_step_s: float,
) -> tuple[JointState, np.ndarray]:
    """From the measured state at every sample k, the model's state and current at k+1."""
    log = data.log
    integral = integral_from_log(log, servo, known.current_limit_torque_nm)
    start = JointState(
        log.motor_angle_rad[:-1],
        log.motor_velocity_rad_s[:-1],
        log.link_angle_rad[:-1],
        data.link_velocity[:-1],
        integral[:-1],
    )
    return advance(
        start, log.goal_rad[:-1], gear, servo, motor, known, log.period_s, physics_step_s
    )


def _cascade_residuals(
    data: _CascadeData,
    gear: GearParams,
    servo: ServoParams,
    motor: MotorParams,
    known: KnownJointFigures,
    physics_step_s: float,
) -> np.ndarray:
    """(N-1, 3): predicted minus measured motor angle, velocity and current at k+1."""
    log = data.log
    state, current = _one_period_predictions(data, gear, servo, motor, known, physics_step_s)
    return np.column_stack(
        [
            state.motor_angle_rad - log.motor_angle_rad[1:],
            state.motor_velocity_rad_s - log.motor_velocity_rad_s[1:],
            current - log.motor_current_a[1:],
        ]
    )


def fit_cascade(
    logs: Sequence[JointLog],
    gear: GearParams,
    known: KnownJointFigures,
    options: IdentificationOptions,
) -> tuple[ServoParams, MotorParams, _FitOutcome]:
    """Kpp, kv, Ti, iota_0 and the motor side by one-period prediction error."""
    data = [
        _CascadeData(log, _split_index(log, options), link_velocity_estimate(log)) for log in logs
    ]
    coords = (
        _Coordinate(_Scale.LOG, 1e-4),  # Kpp
        _Coordinate(_Scale.LOG, 1e-4),  # kv
        _Coordinate(_Scale.LOG, 1e-4),  # Ti
        _Coordinate(_Scale.LINEAR, 1e-3),  # iota_0 [N m]
        _Coordinate(_Scale.LOG, 1e-4),  # Jm
        _Coordinate(_Scale.LINEAR, 1e-3, lower=0.0),  # viscous friction
        _Coordinate(_Scale.LINEAR, 1e-3, lower=0.0),  # Coulomb friction
    )
    values = _cascade_initial_guess(logs, gear, known)

    def channel_rms(values: np.ndarray) -> np.ndarray:
        servo, motor = _split_cascade(values)
        stacked = np.vstack(
            [
                _cascade_residuals(d, gear, servo, motor, known, options.physics_step_s)[
                    : d.split - 1
                ]
                for d in data
            ]
        )
        rms = np.sqrt(np.mean(stacked**2, axis=0))
        return np.maximum(rms, 1e-12)

    outcome = None
    for _ in range(options.reweighting_rounds):
        weights = 1.0 / channel_rms(values)

        def blocks(values: np.ndarray, weights: np.ndarray = weights) -> list[np.ndarray]:
            servo, motor = _split_cascade(values)
            return [
                _cascade_residuals(d, gear, servo, motor, known, options.physics_step_s)[
                    : d.split - 1
                ]
                * weights
                for d in data
            ]

        outcome = _least_squares(blocks, values, coords, options.confidence)
        values = outcome.values
    assert outcome is not None
    servo, motor = _split_cascade(outcome.values)
    return servo, motor, outcome


# ----------------------------------------------------------------------------- current limit


def _current_quantum(logs: Sequence[JointLog]) -> float:
    """The smallest step between distinct current readings (the device's current unit)."""
    gaps = []
    for log in logs:
        levels = np.unique(np.abs(log.motor_current_a))
        steps = np.diff(levels)
        steps = steps[steps > 1e-9]
        if steps.size:
            gaps.append(float(steps.min()))
    return min(gaps) if gaps else 0.0


CAPPED_BAND = 0.05  # readings within this fraction of the largest may be on the limit
MIN_CAPPED_SAMPLES = 5


def _current_limit_estimate(
    logs: Sequence[JointLog],
    data_predictions: Sequence[np.ndarray],
    known: KnownJointFigures,
) -> ParameterEstimate:
    """The current limit: given, reached (the model asked for more and the current stayed at
    its largest reading), or bounded from below by the largest reading."""
    peak = max(float(np.max(np.abs(log.motor_current_a))) for log in logs)
    if known.current_limit_a is not None:
        return ParameterEstimate(
            known.current_limit_a,
            known.current_limit_a,
            known.current_limit_a,
            Status.GIVEN,
            "the actuator's Torque Limit register",
        )
    quantum = max(_current_quantum(logs), 1e-6)
    # The model's own error sets the margin: near the peak the prediction must exceed what
    # was measured by more than it usually misses by, so a peak it merely overshoots is not
    # read as a limit.
    misses = np.concatenate(
        [p - log.motor_current_a[1:] for log, p in zip(logs, data_predictions, strict=True)]
    )
    margin = max(4 * quantum, 4 * float(np.sqrt(np.mean(misses**2))))
    # Capped: a reading near the peak while the servo asked for clearly more. The readings
    # there scatter about the limit with the current's noise, so their largest is above it by
    # a few standard deviations: the limit is the plateau's median, its interval the median's
    # (1.96 standard errors) widened by half a quantum for the rounding.
    capped: list[np.ndarray] = []
    for log, predicted in zip(logs, data_predictions, strict=True):
        measured = np.abs(log.motor_current_a[1:])
        near_peak = measured >= peak - max(2 * quantum, CAPPED_BAND * peak)
        capped.append(measured[near_peak & (np.abs(predicted) > measured + margin)])
    plateau = np.concatenate(capped)
    if plateau.size >= MIN_CAPPED_SAMPLES:
        level = float(np.median(plateau))
        # the median's standard error: sqrt(pi / 2) sigma / sqrt(n) for Gaussian scatter
        half = 1.96 * 1.2533 * float(np.std(plateau)) / math.sqrt(plateau.size) + quantum / 2
        return ParameterEstimate(
            level,
            level - half,
            level + half,
            Status.IDENTIFIED,
            f"reached at {plateau.size} samples (the servo asked for more)",
        )
    return ParameterEstimate(
        math.nan,
        peak,
        math.inf,
        Status.LOWER_BOUND,
        "not reached in the run: only its largest current is known",
    )


# ----------------------------------------------------------------------------- all together


def _estimate(
    outcome: _FitOutcome, index: int, status: Status, note: str = ""
) -> ParameterEstimate:
    return ParameterEstimate(
        float(outcome.values[index]),
        float(outcome.low[index]),
        float(outcome.high[index]),
        status,
        note,
    )


def identify(
    logs: Sequence[JointLog],
    known: KnownJointFigures,
    options: IdentificationOptions | None = None,
) -> IdentificationResult:
    """Fit the joint's constants to one or more logs of the same joint (see the package doc)."""
    options = options or IdentificationOptions()
    if not logs:
        raise ValueError("identify needs at least one log")
    for log in logs:
        if len(log) < MIN_SAMPLES:
            raise LogFormatError(
                f"{log.source}: {len(log)} samples; the fit needs at least {MIN_SAMPLES} "
                "(an identification run lasts tens of seconds)"
            )
    gear, gear_fit = fit_gear(logs, known, options)
    servo_kp, first_order_fit = fit_first_order_servo(logs, options)
    servo, motor, cascade_fit = fit_cascade(logs, gear, known, options)

    # The current limit: unclipped one-period predictions against the largest reading.
    unlimited = replace(known, current_limit_a=None)
    data = [_CascadeData(log, len(log), link_velocity_estimate(log)) for log in logs]
    predictions = [
        _one_period_predictions(d, gear, servo, motor, unlimited, options.physics_step_s)[1]
        for d in data
    ]
    current_limit = _current_limit_estimate(logs, predictions, known)
    notes: list[str] = []
    if current_limit.status is Status.IDENTIFIED and known.current_limit_a is None:
        # Refit the cascade with the cap in the model: the capped samples follow it.
        capped = replace(known, current_limit_a=current_limit.value)
        servo, motor, cascade_fit = fit_cascade(logs, gear, capped, options)
        known_for_model = capped
        notes.append(
            "the run reached the current limit; the cascade was refitted with it in the model"
        )
    else:
        known_for_model = known

    parameters = {
        Parameter.GEAR_STIFFNESS: _estimate(gear_fit, 0, Status.IDENTIFIED),
        Parameter.GEAR_DAMPING: _estimate(gear_fit, 1, Status.IDENTIFIED),
        Parameter.DEFLECTION_OFFSET: _estimate(
            gear_fit, 2, Status.NUISANCE, "the encoders' zero offsets; absorbs K's bias"
        ),
        Parameter.SERVO_KP: _estimate(
            first_order_fit,
            0,
            Status.IDENTIFIED,
            "best first-order fit (4) at this band and amplitude",
        ),
        Parameter.POSITION_GAIN: _estimate(cascade_fit, 0, Status.IDENTIFIED),
        Parameter.VELOCITY_GAIN: _estimate(
            cascade_fit, 1, Status.IDENTIFIED, "scale from the torque constant"
        ),
        Parameter.VELOCITY_INTEGRAL_TIME: _estimate(cascade_fit, 2, Status.IDENTIFIED),
        Parameter.CURRENT_LIMIT: current_limit,
        Parameter.INTEGRAL_INITIAL: _estimate(cascade_fit, 3, Status.NUISANCE),
        Parameter.MOTOR_INERTIA: _estimate(cascade_fit, 4, Status.NUISANCE),
        Parameter.MOTOR_VISCOUS_FRICTION: _estimate(cascade_fit, 5, Status.NUISANCE),
        Parameter.MOTOR_COULOMB_FRICTION: _estimate(cascade_fit, 6, Status.NUISANCE),
    }
    notes.extend(_caveats(logs, parameters, options))

    quality: list[FitQuality] = []
    traces: list[SignalTraces] = []
    for log in logs:
        log_quality, log_traces = _held_out_quality(
            log, gear, servo_kp, servo, motor, known_for_model, options
        )
        quality += log_quality
        traces.append(log_traces)
    return IdentificationResult(
        parameters=parameters,
        quality=tuple(quality),
        known=known,
        sources=tuple(log.source for log in logs),
        notes=tuple(notes),
        traces=tuple(traces),
    )


def _held_out_quality(
    log: JointLog,
    gear: GearParams,
    servo_kp: float,
    servo: ServoParams,
    motor: MotorParams,
    known: KnownJointFigures,
    options: IdentificationOptions,
) -> tuple[list[FitQuality], SignalTraces]:
    """Each model against the held-out samples of one log (all samples if none are held out),
    and the signals for the figure."""
    split = _split_index(log, options)
    held = slice(split, len(log)) if split < len(log) - 10 else slice(1, len(log))
    tag = "" if held.start == split else " (in-sample: nothing held out)"
    link = link_response(log, gear, known)
    goal_hp, motor_hp = _high_pass(log, options.first_order_highpass_hz)
    first_order = first_order_response(goal_hp, motor_hp[0], servo_kp, log.period_s)
    simulated = simulate_joint(log, gear, servo, motor, known, options.physics_step_s)
    _, predicted_current = _one_period_predictions(
        _CascadeData(log, len(log), link_velocity_estimate(log)),
        gear,
        servo,
        motor,
        known,
        options.physics_step_s,
    )
    predicted_current = np.concatenate([[log.motor_current_a[0]], predicted_current])
    deflection = log.link_angle_rad - log.motor_angle_rad
    whole = "whole joint, simulated" + tag
    quality = [
        fit_quality(
            "gear (1) from measured motor" + tag,
            "deflection",
            deflection[held],
            (link.angle_rad - log.motor_angle_rad)[held],
        ),
        fit_quality(
            "first-order servo (4)" + tag,
            "motor angle (high-passed)",
            motor_hp[held],
            first_order[held],
        ),
        fit_quality(
            "cascade, one period ahead" + tag,
            "motor current",
            log.motor_current_a[held],
            predicted_current[held],
        ),
        fit_quality(
            whole, "motor angle", log.motor_angle_rad[held], simulated.motor_angle_rad[held]
        ),
        fit_quality(
            whole,
            "deflection",
            deflection[held],
            (simulated.link_angle_rad - simulated.motor_angle_rad)[held],
        ),
        fit_quality(
            whole, "motor current", log.motor_current_a[held], simulated.motor_current_a[held]
        ),
    ]
    traces = SignalTraces(
        log=log,
        holdout_start_index=split,
        motor_angle_sim_rad=simulated.motor_angle_rad,
        link_angle_sim_rad=simulated.link_angle_rad,
        motor_current_sim_a=simulated.motor_current_a,
        deflection_from_motor_rad=link.angle_rad - log.motor_angle_rad,
        first_order_motor_rad=first_order,
        first_order_measured_rad=motor_hp,
    )
    return quality, traces


def _caveats(
    logs: Sequence[JointLog],
    parameters: dict[Parameter, ParameterEstimate],
    options: IdentificationOptions,
) -> list[str]:
    """Warnings about what the data could not pin down."""
    notes = []
    fitted_s = sum(log.time_s[_split_index(log, options) - 1] - log.time_s[0] for log in logs)
    integral_time = parameters[Parameter.VELOCITY_INTEGRAL_TIME].value
    if fitted_s < 2 * integral_time:
        notes.append(
            f"the fitted data span {fitted_s:.1f} s, less than twice the velocity integral "
            f"time ({integral_time:.1f} s): its estimate rests on a small part of its effect"
        )
    for parameter in (
        Parameter.GEAR_STIFFNESS,
        Parameter.GEAR_DAMPING,
        Parameter.SERVO_KP,
        Parameter.POSITION_GAIN,
        Parameter.VELOCITY_GAIN,
        Parameter.VELOCITY_INTEGRAL_TIME,
    ):
        estimate = parameters[parameter]
        width = (estimate.high - estimate.low) / (2 * abs(estimate.value))
        if not width < 0.1:
            notes.append(
                f"{parameter.value}: the 95 % interval is +-{100 * width:.0f} % wide; "
                "excite longer or with more amplitude"
            )
    return notes
