"""What one SYNC of the CAN sensors returns (SI units, validity, ages, bus state)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ForceReading:
    """The force sensor's answer to one SYNC (fields as in LinkReading, scalar)."""

    force_n: float  # NaN when not valid
    valid: bool
    age_s: float
    stale: bool
    raw: int
    nmt_state: str
    heartbeat_age_s: float
    heartbeat_lost: bool


@dataclass(frozen=True)
class WrenchReading:
    """A six-axis force/torque sensor's answer to one SYNC (SI; NaN where not valid).

    force_n, torque_nm: what the sensor measures in its own frame (for the emulated DYROS-JET
    feet: the ground's wrench on the robot, the moment about the sensor's origin), tare
    removed. valid: both TPDOs of this SYNC arrived. raw: the six process values last received.
    Other fields as ForceReading.
    """

    label: str
    force_n: np.ndarray
    torque_nm: np.ndarray
    valid: bool
    age_s: float
    stale: bool
    raw: np.ndarray
    nmt_state: str
    heartbeat_age_s: float
    heartbeat_lost: bool


@dataclass(frozen=True)
class LinkReading:
    """The link encoders' answers to one SYNC; arrays have one entry per configured encoder.

    sync_time_s: the reader's clock when the SYNC was sent (the instant the values belong to).
    angles_rad: link angle in rad, NaN where no answer to this SYNC arrived.
    valid: an answer to this SYNC arrived. age_s: time since the last valid value (0 when
    valid, inf before the first). stale: age_s > the encoder's stale_after_s.
    raw_counts: the last count received (held where not valid; 0 before the first).
    raw_changed: valid and different from the previous valid count. unchanged_count: how many
    valid readings in a row repeated the same count (a frozen counter keeps counting up; a
    healthy encoder at rest may too, so judge it together with the commanded motion).
    nmt_state: the node's NMT state from its last heartbeat ("UNKNOWN" before any).
    heartbeat_age_s / heartbeat_lost: time since its last heartbeat / older than
    heartbeat_timeout_factor x its heartbeat period.
    events: what happened on the bus since the previous reading (boot-ups, state changes,
    EMCY, late or short TPDOs), for the log.
    wrenches: the six-axis force/torque sensors' answers (WrenchReading), if configured.
    """

    sync_time_s: float
    angles_rad: np.ndarray
    valid: np.ndarray
    age_s: np.ndarray
    stale: np.ndarray
    raw_counts: np.ndarray
    raw_changed: np.ndarray
    unchanged_count: np.ndarray
    nmt_state: tuple[str, ...]
    heartbeat_age_s: np.ndarray
    heartbeat_lost: np.ndarray
    force: ForceReading | None
    events: tuple[str, ...]
    wrenches: tuple[WrenchReading, ...] = ()  # force/torque sensors, in configuration order

    @property
    def all_valid(self) -> bool:
        """Every encoder (and every force or force/torque sensor configured) answered."""
        return (
            bool(self.valid.all())
            and (self.force is None or self.force.valid)
            and all(wrench.valid for wrench in self.wrenches)
        )
