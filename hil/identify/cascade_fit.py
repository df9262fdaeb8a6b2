"""Fit 3, the actuator's cascade: Kpp, kv, Ti (with iota_0 and the motor side, Jm, b, F_c, as
nuisance), by prediction error over one loop period from each measured state
(`models.advance`), on the motor angle, velocity and current; K and D from fit 1 (`gear_fit`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from hil.identify.least_squares import Coordinate, FitOutcome, Scale, least_squares
from hil.identify.models import (
    GearParams,
    JointState,
    MotorParams,
    ServoParams,
    advance,
    goal_integral,
    integral_from_log,
    link_velocity_estimate,
)
from hil.identify.options import IdentificationOptions, split_index
from hil.identify.records import JointLog, KnownJointFigures


@dataclass(frozen=True)
class CascadeData:
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


def one_period_predictions(
    data: CascadeData,
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
    data: CascadeData,
    gear: GearParams,
    servo: ServoParams,
    motor: MotorParams,
    known: KnownJointFigures,
    physics_step_s: float,
) -> np.ndarray:
    """(N-1, 3): predicted minus measured motor angle, velocity and current at k+1."""
    log = data.log
    state, current = one_period_predictions(data, gear, servo, motor, known, physics_step_s)
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
) -> tuple[ServoParams, MotorParams, FitOutcome]:
    """Kpp, kv, Ti, iota_0 and the motor side by one-period prediction error."""
    data = [
        CascadeData(log, split_index(log, options), link_velocity_estimate(log)) for log in logs
    ]
    coords = (
        Coordinate(Scale.LOG, 1e-4),  # Kpp
        Coordinate(Scale.LOG, 1e-4),  # kv
        Coordinate(Scale.LOG, 1e-4),  # Ti
        Coordinate(Scale.LINEAR, 1e-3),  # iota_0 [N m]
        Coordinate(Scale.LOG, 1e-4),  # Jm
        Coordinate(Scale.LINEAR, 1e-3, lower=0.0),  # viscous friction
        Coordinate(Scale.LINEAR, 1e-3, lower=0.0),  # Coulomb friction
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

        outcome = least_squares(blocks, values, coords, options.confidence)
        values = outcome.values
    assert outcome is not None
    servo, motor = _split_cascade(outcome.values)
    return servo, motor, outcome
