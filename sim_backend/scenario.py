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
        duration_ok = self.duration_s is None or (
            math.isfinite(self.duration_s) and self.duration_s > 0
        )
        if not (math.isfinite(self.start_s) and self.start_s >= 0 and duration_ok):
            raise ValueError(
                f"fault {self.kind}: start must be a finite time >= 0 s and the duration a "
                f"finite time > 0 s, got start {self.start_s} s, duration {self.duration_s} s"
            )
        if not (math.isfinite(self.noise_counts_rms) and self.noise_counts_rms >= 0):
            raise ValueError(f"fault {self.kind}: noise must be finite and >= 0 counts rms")
        if self.joint < 0:
            raise ValueError(f"fault {self.kind}: joint index must be >= 0, got {self.joint}")

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
    pelvis_pushes: tuple[PelvisPushEvent, ...] = ()  # the humanoid's

    def to_dict(self) -> dict:
        return {
            "pushes": [vars(p) for p in self.pushes],
            "faults": [vars(f) for f in self.faults],
            "obstacle_contact_angle_rad": self.obstacle_contact_angle_rad,
            "pelvis_pushes": [vars(p) for p in self.pelvis_pushes],
        }

    @classmethod
    def from_dict(cls, data: dict) -> Scenario:
        unknown = set(data) - {"pushes", "faults", "obstacle_contact_angle_rad", "pelvis_pushes"}
        if unknown:
            raise ValueError(f"unknown scenario keys {sorted(unknown)}")
        return cls(
            pushes=tuple(PushEvent(**p) for p in data.get("pushes", [])),
            faults=tuple(FaultEvent(**f) for f in data.get("faults", [])),
            obstacle_contact_angle_rad=data.get("obstacle_contact_angle_rad"),
            pelvis_pushes=tuple(
                PelvisPushEvent(p["start_s"], p["duration_s"], tuple(p["force_n"]))
                for p in data.get("pelvis_pushes", [])
            ),
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


@dataclass
class ActiveFaults:
    """The faults in force at one instant, by joint index (see `FaultSchedule.at`)."""

    silent: set[int]
    dropped: set[int]  # every reply of these joints' actuators is lost
    corrupted: set[int]  # every reply arrives with a bad CRC
    drop_next: list[int]  # one-shot: the next reply of each listed joint is lost
    corrupt_next: list[int]  # one-shot: the next reply arrives corrupted
    encoder_mode: list[str]  # per joint: "ok", "dead", "stale" or "noisy"
    encoder_noise_counts_rms: list[float]


class FaultSchedule:
    """Which injected faults are in force when, for `n_joints` joints; one-shot faults fire once.

    `fired[i]` counts how often fault i of the scenario took effect (a window counts once when
    it opens, a one-shot when it is armed), so a test can check that what it injected happened.
    """

    def __init__(self, faults: tuple[FaultEvent, ...], n_joints: int) -> None:
        for fault in faults:
            if not 0 <= fault.joint < n_joints:
                raise ValueError(
                    f"fault {fault.kind}: joint index {fault.joint} out of range 0..{n_joints - 1}"
                )
        self.faults = faults
        self.n_joints = n_joints
        self.fired = [0] * len(faults)
        self._active = [False] * len(faults)

    def at(self, now_s: float | None) -> ActiveFaults:
        n = self.n_joints
        active = ActiveFaults(set(), set(), set(), [], [], ["ok"] * n, [0.0] * n)
        for number, event in enumerate(self.faults):
            on = now_s is not None and event.start_s <= now_s < event.end_s
            if on and not self._active[number]:
                self.fired[number] += 1
            was_on, self._active[number] = self._active[number], on
            if not on:
                continue
            if event.kind in ONE_SHOT_FAULTS and event.duration_s is None:
                if not was_on:  # armed once, when its time comes
                    target = (
                        active.drop_next if event.kind == "dropped_reply" else active.corrupt_next
                    )
                    target.append(event.joint)
                continue
            _activate(event, active)
        return active


def _activate(event: FaultEvent, active: ActiveFaults) -> None:
    joint = event.joint
    if event.kind == "silent_id":
        active.silent.add(joint)
    elif event.kind == "dropped_reply":
        active.dropped.add(joint)
    elif event.kind == "corrupt_crc":
        active.corrupted.add(joint)
    elif event.kind == "dead_encoder":
        active.encoder_mode[joint] = "dead"
    elif event.kind == "stale_encoder":
        active.encoder_mode[joint] = "stale"
    elif event.kind == "noisy_encoder":
        active.encoder_mode[joint] = "noisy"
        active.encoder_noise_counts_rms[joint] = event.noise_counts_rms


@dataclass(frozen=True)
class PelvisPushEvent:
    """A force [N] (world frame) on the humanoid's pelvis from start_s for duration_s."""

    start_s: float
    duration_s: float
    force_n: tuple[float, float, float]
