"""Fit 2, the paper's first-order servo (4): Kp, by output error of the motor angle simulated
from the goal, both high-passed alike (the first-order model has no gravity: its slow position
lag, which the weak integral winds out, would otherwise be read as lag).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import scipy.signal

from hil.identify.least_squares import Coordinate, FitOutcome, Scale, least_squares
from hil.identify.models import first_order_response
from hil.identify.options import IdentificationOptions, split_index
from hil.identify.records import JointLog


def high_pass(log: JointLog, corner_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Goal and motor angle through the same 2nd-order Butterworth high-pass, from rest."""
    b, a = scipy.signal.butter(2, corner_hz, btype="highpass", fs=1.0 / log.period_s)
    goal = scipy.signal.lfilter(b, a, log.goal_rad - log.goal_rad[0])
    motor = scipy.signal.lfilter(b, a, log.motor_angle_rad - log.motor_angle_rad[0])
    return goal, motor


def fit_first_order_servo(
    logs: Sequence[JointLog], options: IdentificationOptions
) -> tuple[float, FitOutcome]:
    """Kp of (4): the motor angle simulated from the goal, both high-passed (output error).

    The high-pass commutes with the linear model (4), so the fit is that of (4) itself on the
    band the excitation covers, without the slow gravity lag the model does not have. Both
    filters start from rest: the log must start with the motor at rest on its goal (as a run
    does, holding where torque came on).
    """
    splits = [split_index(log, options) for log in logs]
    filtered = [high_pass(log, options.first_order_highpass_hz) for log in logs]
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
    outcome = least_squares(
        blocks, np.array([initial]), (Coordinate(Scale.LOG, 1e-4),), options.confidence
    )
    return float(outcome.values[0]), outcome
