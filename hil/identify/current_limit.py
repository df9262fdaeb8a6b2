"""The current limit: given (the actuator's Torque Limit register), reached in the run (the
cascade's unclipped prediction asked for more while the current stayed at its largest reading),
or bounded from below by the largest reading.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from hil.identify.records import JointLog, KnownJointFigures
from hil.identify.result import ParameterEstimate, Status


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


def current_limit_estimate(
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
