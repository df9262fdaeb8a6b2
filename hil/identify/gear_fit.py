"""Fit 1, the gear: K, D and the deflection offset delta_0 of (1), by output error of the link
angle simulated by (1), (3) from the measured motor motion (`models.link_response`). The motor's
own model does not enter, so its errors (friction) cannot bias K and D.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hil.identify.least_squares import Coordinate, FitOutcome, Scale, least_squares
from hil.identify.models import GearParams, link_response, link_velocity_estimate
from hil.identify.options import IdentificationOptions, split_index
from hil.identify.records import JointLog, KnownJointFigures


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
) -> tuple[GearParams, FitOutcome]:
    """K, D and the deflection offset from the link angle (output error, measured motor in)."""
    splits = [split_index(log, options) for log in logs]
    scale = 1e-5  # rad: residuals near one count of the link encoder

    def blocks(values: np.ndarray) -> list[np.ndarray]:
        gear = GearParams(*values)
        out = []
        for log, split in zip(logs, splits, strict=True):
            link = link_response(log, gear, known)
            out.append(((link.angle_rad - log.link_angle_rad)[1:split] / scale)[:, None])
        return out

    coords = (
        Coordinate(Scale.LOG, 1e-4),
        Coordinate(Scale.LOG, 1e-4),
        Coordinate(Scale.LINEAR, 1e-7),
    )
    outcome = least_squares(blocks, _gear_initial_guess(logs, known), coords, options.confidence)
    return GearParams(*outcome.values), outcome
