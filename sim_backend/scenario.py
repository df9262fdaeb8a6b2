"""What happens to the emulated testbed during a run: pushes on the load and injected faults.

Times count from the first CAN SYNC the emulator receives (the loop's tick 0), on the plant's
clock in lock-step mode and on the wall clock in real-time mode.

Fault kinds (what a user can rehearse with `--inject KIND@START[+DURATION]`):

    dropped_reply   the actuator executes the instruction but its status packet never arrives
    corrupt_crc     the actuator's status packet arrives with a wrong CRC
    silent_id       the actuator answers nothing (unplugged, wrong ID, dead)
    dead_encoder    the link-encoder node goes silent: no TPDO, no heartbeat
    stale_encoder   the link-encoder node keeps answering SYNC with a frozen position
    noisy_encoder   the link-encoder position gets Gaussian noise (default 50 counts rms)

dropped_reply and corrupt_crc without a duration hit one reply; with a duration, every reply in
the window. The others last for the duration, or to the end of the run without one.
Host-side faults (a loop overrun) are injected by the loop itself, not here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

BUS_FAULTS = ("dropped_reply", "corrupt_crc", "silent_id")
ENCODER_FAULTS = ("dead_encoder", "stale_encoder", "noisy_encoder")
EMULATOR_FAULTS = BUS_FAULTS + ENCODER_FAULTS
ONE_SHOT_FAULTS = ("dropped_reply", "corrupt_crc")
DEFAULT_NOISE_COUNTS_RMS = 50.0


@dataclass(frozen=True)
class FaultEvent:
    kind: str
    start_s: float
    duration_s: float | None = None  # None: one reply (one-shot kinds) or to the end
    joint: int = 0  # index into the configured joints
    noise_counts_rms: float = DEFAULT_NOISE_COUNTS_RMS

    def __post_init__(self) -> None:
        if self.kind not in EMULATOR_FAULTS:
            raise ValueError(
                f"unknown emulator fault {self.kind!r}; choose one of {list(EMULATOR_FAULTS)}"
            )
        # `not (x >= 0)` also refuses NaN, which compares false with everything: a fault at NaN
        # would silently never fire.
        duration_ok = self.duration_s is None or (
            math.isfinite(self.duration_s) and self.duration_s > 0
        )
        if not (math.isfinite(self.start_s) and self.start_s >= 0) or not duration_ok:
            raise ValueError(
                f"fault {self.kind}: start must be a finite time >= 0 s and duration a finite "
                f"time > 0 s, got start {self.start_s!r}, duration {self.duration_s!r}"
            )
        if not (math.isfinite(self.noise_counts_rms) and self.noise_counts_rms >= 0):
            raise ValueError(
                f"fault {self.kind}: noise_counts_rms must be finite and >= 0, "
                f"got {self.noise_counts_rms!r}"
            )

    @property
    def end_s(self) -> float:
        return math.inf if self.duration_s is None else self.start_s + self.duration_s


@dataclass(frozen=True)
class PushEvent:
    """Force [N] perpendicular to link `joint`, positive towards increasing link angle."""

    start_s: float
    duration_s: float
    force_n: float
    joint: int = 0

    def force_at(self, time_s: float) -> float:
        return self.force_n if self.start_s <= time_s < self.start_s + self.duration_s else 0.0


@dataclass(frozen=True)
class Scenario:
    pushes: tuple[PushEvent, ...] = ()
    faults: tuple[FaultEvent, ...] = ()
    obstacle_contact_angle_rad: float | None = None  # None: no block in reach

    def to_dict(self) -> dict:
        return {
            "pushes": [vars(p) for p in self.pushes],
            "faults": [vars(f) for f in self.faults],
            "obstacle_contact_angle_rad": self.obstacle_contact_angle_rad,
        }

    @classmethod
    def from_dict(cls, data: dict) -> Scenario:
        unknown = set(data) - {"pushes", "faults", "obstacle_contact_angle_rad"}
        if unknown:
            raise ValueError(f"unknown scenario keys {sorted(unknown)}")
        return cls(
            pushes=tuple(PushEvent(**p) for p in data.get("pushes", [])),
            faults=tuple(FaultEvent(**f) for f in data.get("faults", [])),
            obstacle_contact_angle_rad=data.get("obstacle_contact_angle_rad"),
        )


def parse_fault(text: str, joint: int = 0) -> FaultEvent:
    """'silent_id@2.5+0.5' -> FaultEvent('silent_id', 2.5, 0.5). '@START' defaults to 0."""
    kind, _, when = text.partition("@")
    start, _, duration = when.partition("+")
    try:
        start_s = float(start) if start else 0.0
        duration_s = float(duration) if duration else None
    except ValueError:
        raise ValueError(
            f"bad fault {text!r}: expected KIND[@START[+DURATION]] with times in seconds"
        ) from None
    return FaultEvent(kind=kind.strip(), start_s=start_s, duration_s=duration_s, joint=joint)
