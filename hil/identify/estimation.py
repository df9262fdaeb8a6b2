"""The whole identification (`identify`): the three least-squares fits, one per part of the joint
(package docstring), the current limit, and each model's quality on the held-out samples.

1. The gear, K, D and the deflection offset: `gear_fit.py`.
2. The paper's first-order servo (4), Kp: `servo_fit.py`.
3. The actuator's cascade, Kpp, kv, Ti (and the motor side it needs), K and D from fit 1:
   `cascade_fit.py`; the current limit from its unclipped predictions: `current_limit.py`.
Each fit uses the samples before the hold-out point (`options.py`); the rest measure the fit
quality. The least-squares fit with its intervals: `least_squares.py`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from hil.identify.cascade_fit import CascadeData, fit_cascade, one_period_predictions
from hil.identify.current_limit import current_limit_estimate
from hil.identify.gear_fit import fit_gear
from hil.identify.least_squares import FitOutcome
from hil.identify.models import (
    GearParams,
    MotorParams,
    ServoParams,
    first_order_response,
    link_response,
    link_velocity_estimate,
    simulate_joint,
)
from hil.identify.options import IdentificationOptions, split_index
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
from hil.identify.servo_fit import fit_first_order_servo, high_pass

__all__ = [
    "IdentificationOptions",
    "fit_cascade",
    "fit_first_order_servo",
    "fit_gear",
    "identify",
]


def _estimate(outcome: FitOutcome, index: int, status: Status, note: str = "") -> ParameterEstimate:
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
    data = [CascadeData(log, len(log), link_velocity_estimate(log)) for log in logs]
    predictions = [
        one_period_predictions(d, gear, servo, motor, unlimited, options.physics_step_s)[1]
        for d in data
    ]
    current_limit = current_limit_estimate(logs, predictions, known)
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
    split = split_index(log, options)
    held = slice(split, len(log)) if split < len(log) - 10 else slice(1, len(log))
    tag = "" if held.start == split else " (in-sample: nothing held out)"
    link = link_response(log, gear, known)
    goal_hp, motor_hp = high_pass(log, options.first_order_highpass_hz)
    first_order = first_order_response(goal_hp, motor_hp[0], servo_kp, log.period_s)
    simulated = simulate_joint(log, gear, servo, motor, known, options.physics_step_s)
    _, predicted_current = one_period_predictions(
        CascadeData(log, len(log), link_velocity_estimate(log)),
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
    fitted_s = sum(log.time_s[split_index(log, options) - 1] - log.time_s[0] for log in logs)
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
