"""The legs' identification excitation (`hil run suspended-chirp`): DYROS-JET hung by its
pelvis from a gantry, each leg joint chirped in turn, open loop - the log `hil twin` fits the
twelve joints from.

Legged robots are identified hung up, feet free, one joint moving at a time, so that each
joint's servo and gear are seen against a known, unchanging load: the links below it. The
robot hangs in the walking-ready posture (knees bent, so that gravity loads the knees and
ankles as it does standing and the servos' weak integral action has something to wind out);
the experiment then sweeps the goal of one joint of each leg at a time - the left and the
right hip yaw together, then the hip rolls, ... the ankle rolls - with the rate-limited
logarithmic chirp of `hil.identify.excitation`: per window a hold, an up-sweep (fitted), a
shorter down-sweep (held out: the samples the twin's friction model is chosen on and its
prediction measured on), a hold. With the pelvis fixed the two legs do not act on each other,
and within a leg the joints not being swept hold their goal.

Each joint's chirp is its own (`LegChirp`: amplitude, band, goal rate), chosen for what it
swings: a hip pitch or roll swings the whole leg (~1.5 kg m^2 about the hip), so its band
stops lower (3 Hz) and its goal rate is halved, or the chirp's top would ask the H54 for more
than its 44.7 N m; an ankle swings the foot alone. The sweeps run open loop (no controller),
the supervisor still checking every goal: rates below its limit, amplitudes within the joints'
limits (checked before the run).

On hardware: hang the robot by its pelvis (its gantry or a crane), feet well off the floor,
then `hil run suspended-chirp --config robot.toml`. The emulator hangs it
(`World.suspended`).

Metrics: those of `identify` (peak current, peak goal rate, coverage), and the held-out
windows (`held_out_mask`, loop ticks) the fit reads from the experiment itself.
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass
from typing import Any

import numpy as np

from hil.experiments.base import Experiment, World
from hil.experiments.identify import EXCITATION_COLUMNS, excitation_metrics
from hil.identify import ChirpExcitation, chirp_goal_offsets
from hil.output.report import Column
from hil.output.rundir import RunData

JOINTS_PER_LEG = 6  # hip yaw, roll, pitch, knee, ankle pitch, roll (the lab's order)


@dataclass(frozen=True)
class LegChirp:
    """One joint's chirp (SI): the largest goal excursion, the swept band, the goal's rate."""

    amplitude_rad: float
    start_frequency_hz: float
    stop_frequency_hz: float
    max_goal_rate_rad_s: float


# Per joint of a leg (the lab's order), what it swings decides its chirp (module docstring).
LEG_CHIRPS: tuple[LegChirp, ...] = (
    LegChirp(0.12, 0.3, 5.0, 1.2),  # hip yaw: the leg about its own axis (~0.1 kg m^2)
    LegChirp(0.08, 0.3, 3.0, 0.6),  # hip roll: the whole leg sideways
    LegChirp(0.08, 0.3, 3.0, 0.6),  # hip pitch: the whole leg forward
    LegChirp(0.10, 0.3, 4.0, 0.8),  # knee: the shank and foot
    LegChirp(0.12, 0.3, 5.0, 1.2),  # ankle pitch: the foot
    LegChirp(0.12, 0.3, 5.0, 1.2),  # ankle roll: the foot
)


@dataclass(frozen=True)
class SuspendedChirpExperiment(Experiment):
    """Each leg joint chirped in turn, the robot hung by its pelvis; see the module docstring.

    posture_rad: the 12 link angles it hangs in (the lab's leg order).
    chirps: per joint of a leg, its chirp (the left and right joint get the same).
    settle_s, fit_sweep_s, validation_sweep_s, taper_s: each window's holds and sweeps.
    """

    __test__ = False

    name: str
    title: str
    posture_rad: tuple[float, ...]
    chirps: tuple[LegChirp, ...] = LEG_CHIRPS
    settle_s: float = 1.0
    fit_sweep_s: float = 6.0
    validation_sweep_s: float = 3.0
    taper_s: float = 0.5
    period_s: float = 0.005
    world: World = World(suspended=True)

    def __post_init__(self) -> None:
        if len(self.posture_rad) != 2 * JOINTS_PER_LEG:
            raise ValueError(f"posture_rad needs {2 * JOINTS_PER_LEG} angles")
        if len(self.chirps) != JOINTS_PER_LEG:
            raise ValueError(f"chirps needs one LegChirp per joint of a leg ({JOINTS_PER_LEG})")
        self.excitation(0)  # each window's figures checked (ChirpExcitation's own checks)

    def excitation(self, joint: int, period_s: float | None = None) -> ChirpExcitation:
        """The chirp of a leg's joint `joint` (0 hip yaw ... 5 ankle roll) as one window."""
        chirp = self.chirps[joint]
        return ChirpExcitation(
            holding_angle_rad=0.0,
            amplitude_rad=chirp.amplitude_rad,
            start_frequency_hz=chirp.start_frequency_hz,
            stop_frequency_hz=chirp.stop_frequency_hz,
            fit_sweep_duration_s=self.fit_sweep_s,
            validation_sweep_duration_s=self.validation_sweep_s,
            settle_duration_s=self.settle_s,
            taper_duration_s=self.taper_s,
            max_goal_rate_rad_s=chirp.max_goal_rate_rad_s,
            min_angle_rad=-chirp.amplitude_rad,
            max_angle_rad=chirp.amplitude_rad,
            period_s=period_s or self.period_s,
        )

    @property
    def window_s(self) -> float:
        return self.excitation(0).duration_s

    @property
    def duration_s(self) -> float:  # type: ignore[override]
        return JOINTS_PER_LEG * self.window_s

    @property
    def open_loop(self) -> bool:
        return True

    def support(self, time_s: float) -> object:
        """The humanoid's model knows no hanging robot; no controller steps in this open-loop
        experiment, so its support is only what the loop's tables are built on: double."""
        from controller.humanoid import SupportState

        return SupportState.DOUBLE

    @functools.cached_property
    def _offsets(self) -> np.ndarray:
        return self._offsets_at(self.period_s)

    def _offsets_at(self, period_s: float) -> np.ndarray:
        """(ticks, 12) goal offsets: window w sweeps joint w of both legs."""
        windows = [chirp_goal_offsets(self.excitation(w, period_s)).goal_offset_rad for w in
                   range(JOINTS_PER_LEG)]  # fmt: skip
        table = np.zeros((sum(len(w) for w in windows), 2 * JOINTS_PER_LEG))
        start = 0
        for joint, offsets in enumerate(windows):
            for leg in range(2):
                table[start : start + len(offsets), leg * JOINTS_PER_LEG + joint] = offsets
            start += len(offsets)
        return table

    def held_out_mask(self, period_s: float, ticks: int) -> np.ndarray:
        """(ticks,) True on the experiment's ticks whose goals are a window's held-out part
        (its down-sweep and last hold), experiment tick 0 first."""
        mask = np.zeros(ticks, dtype=bool)
        window = int(round(self.window_s / period_s))
        held = int(round(self.excitation(0, period_s).validation_start_s / period_s))
        for w in range(JOINTS_PER_LEG):
            mask[w * window + held : (w + 1) * window] = True
        return mask

    # --- what the loop follows ------------------------------------------------------------
    def reference(self, time_s: float) -> np.ndarray:
        """The links' nominal path: the hanging posture plus the goals' offsets."""
        offsets = self._offsets
        index = int(round(time_s / self.period_s))
        row = offsets[index] if 0 <= index < len(offsets) else np.zeros(offsets.shape[1])
        return np.asarray(self.posture_rad) + row

    def reference_range(self, n_joints: int) -> tuple[np.ndarray, np.ndarray]:
        posture = np.asarray(self.posture_rad)
        swing = np.abs(self._offsets).max(axis=0)
        return posture - swing, posture + swing

    def goal_offsets(self, period_s: float, ticks: int, n_joints: int) -> np.ndarray:
        offsets = self._offsets_at(period_s)[:ticks]
        table = np.zeros((ticks, n_joints))
        table[: len(offsets)] = offsets
        return table

    def parameters(self) -> dict[str, Any]:
        return {
            "excitation": "suspended chirp, one joint of each leg at a time",
            "posture_rad": list(self.posture_rad),
            "chirps": [dataclasses.asdict(c) for c in self.chirps],
            "settle_s": self.settle_s,
            "fit_sweep_s": self.fit_sweep_s,
            "validation_sweep_s": self.validation_sweep_s,
            "window_s": self.window_s,
        }

    # --- after a run -----------------------------------------------------------------------
    def metrics(self, run: RunData) -> dict[str, Any]:
        return excitation_metrics(run, self._offsets_at)

    @property
    def report_columns(self) -> tuple[Column, ...]:
        return EXCITATION_COLUMNS


def _walking_ready() -> tuple[float, ...]:
    from controller.humanoid import WALKING_READY_LEG_ANGLES_RAD

    return tuple(WALKING_READY_LEG_ANGLES_RAD)


SUSPENDED_CHIRP = SuspendedChirpExperiment(
    name="suspended-chirp",
    title="DYROS-JET hung by its pelvis, each leg joint chirped in turn (for `hil twin`)",
    posture_rad=_walking_ready(),
)
