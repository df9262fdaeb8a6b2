"""How the identification fits (`IdentificationOptions`) and where each log's held-out samples
begin: every fit uses the samples before that point, the quality measures the rest.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hil.identify.records import JointLog


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


def split_index(log: JointLog, options: IdentificationOptions) -> int:
    """First held-out sample of a log (len(log) if nothing is held out)."""
    if options.validation_start_s is not None:
        split = int(np.searchsorted(log.time_s, options.validation_start_s))
    else:
        split = int(round((1.0 - options.holdout_fraction) * len(log)))
    return min(max(split, 2), len(log))
