"""One tick of a run's log as numbers (`TickSample`): what the views derived from the log (the
ROS 2 bag, the robot's frames in run.mcap) are made of, read either from a finished run
directory (hil/output/run_samples.py) or from the run log's own messages while the run goes
(`TickAssembler`: /joints and /loop, hil/output/channels.py). Both hold log.csv's values: the
messages carry the row's own cells, so the two readings are the same floats."""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

# The per-joint columns the views use (the bag's joint states, the frames' link angles)
VIEW_COLUMNS = ("motor_angle_rad", "link_angle_rad", "deflection_rad", "motor_velocity_rad_s")


@dataclass(frozen=True)
class TickSample:
    """A log.csv row: per-joint columns (arrays in joint order, NaN where not read) and the
    named sensors."""

    tick: int
    time_s: float
    joints: Mapping[str, np.ndarray]
    sensors: Mapping[str, float]


class TickAssembler:
    """A tick from the run log's messages: /joints, then /loop completes it."""

    def __init__(self, per_joint: tuple[str, ...], sensors: tuple[str, ...]) -> None:
        self.per_joint = per_joint
        self.sensors = sensors
        self._joints: dict[str, object] | None = None

    def joints(self, data: bytes) -> None:
        self._joints = json.loads(data)

    def loop(self, data: bytes) -> TickSample | None:
        """The tick, once its /loop message has come (None without its /joints)."""
        joints, self._joints = self._joints, None
        if joints is None:
            return None
        loop = json.loads(data)
        return TickSample(
            int(loop["tick"]),
            float(loop["time_s"]),
            {c: _floats(joints[c]) for c in self.per_joint if c in joints},
            {c: _float(loop.get(c)) for c in self.sensors},
        )


def _floats(values: object) -> np.ndarray:
    return np.array([math.nan if v is None else float(v) for v in values], dtype=float)  # type: ignore[attr-defined]


def _float(value: object) -> float:
    return math.nan if value is None else float(value)  # type: ignore[arg-type]
