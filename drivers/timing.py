"""Summaries of measured durations [s]: what the benches print (driver and loop alike)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class DurationStats:
    """count, min, median, 90th and 99th percentile, max of a sample of durations [s]
    (non-finite samples are left out; an empty sample gives NaN figures)."""

    count: int
    min_s: float
    median_s: float
    p90_s: float
    p99_s: float
    max_s: float

    @classmethod
    def of(cls, samples_s: np.ndarray) -> DurationStats:
        samples = np.asarray(samples_s, dtype=float)
        samples = samples[np.isfinite(samples)]
        if samples.size == 0:
            return cls(0, math.nan, math.nan, math.nan, math.nan, math.nan)
        return cls(
            count=int(samples.size),
            min_s=float(samples.min()),
            median_s=float(np.median(samples)),
            p90_s=float(np.percentile(samples, 90)),
            p99_s=float(np.percentile(samples, 99)),
            max_s=float(samples.max()),
        )

    def text(self, scale: float = 1e3) -> str:
        """'median / p99 / max' in ms (scale 1e3)."""
        return f"{self.median_s * scale:.3f} / {self.p99_s * scale:.3f} / {self.max_s * scale:.3f}"
