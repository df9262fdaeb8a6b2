"""The humanoid's standing experiments (DYROS-JET's legs; Kim et al., ICRA 2018, Sec. IV-C).

    stand   hold the walking-ready posture (knees bent, CoM over the middle of the feet) in
            double support: how far the flexible legs let the pelvis tilt and the ZMP wander,
            with and without the gravity compensator
    push    the same, with a push on the pelvis: how far the ZMP goes, how long until it is back,
            whether the robot falls

Everything is measured from what the robot's own sensors report over the bus, as it would be on
the real robot: the ZMP from the two feet's force/torque sensors (their pose from the measured
link angles, the support sole flat on level ground), the pelvis tilt from the measured link
angles through the legs' kinematics. The robot's model for that is the controller's (pinocchio,
from the URDF: `controller.humanoid`), not the emulator's.

Metrics (loop time; "settled" = after SETTLE_S of the experiment):
    pelvis_tilt_rad       largest pelvis tilt from upright, settled (kinematic estimate)
    max_deflection_rad    largest |link - motor| of any joint, settled
    zmp_max_error_m       largest distance of the measured ZMP from the desired one (the
                          desired posture's CoM on the ground), settled
    zmp_rms_error_m       its rms
    fell                  the measured ZMP left the support polygon (by FALL_MARGIN_M) for
                          FALL_TIME_S, or the feet carried less than half the weight, or the
                          pelvis tilted more than FALL_TILT_RAD
    push: zmp_excursion_m (largest distance from the ZMP just before the push) and
          recovery_time_s (from the push until the ZMP stays within RECOVERED_M of it)

Per tick (`derived_series`): kinematics.csv in the run directory, the ZMP, its desired value,
the CoM, the pelvis tilt, the support margin and the feet's vertical forces that these metrics
are computed from (hil/output/series.py).
"""

from __future__ import annotations

import contextlib
import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from drivers.joint_bus import wrench_keys
from hil.experiments.base import Experiment, PelvisPush, World
from hil.experiments.legs import FEET, leg_model, on_feet, pelvis_rotation
from hil.output.plots import (
    ComparisonRun,
    WorldMarks,
    comparison_title,
    in_drawing_order,
    mark_world,
    save_figure,
)
from hil.output.plots import Push as PushMark
from hil.output.records import RunEntry
from hil.output.report import Column, Missing, Relation, check, find, metric, number
from hil.output.rundir import RunData
from hil.output.series import DerivedSeries, kinematics_series
from hil.vocabulary import ControllerKind, ReactionPolicy

SETTLE_S = 1.0  # the robot starts unloaded on its springs: the first second is the settling
FALL_MARGIN_M = 0.01
FALL_TIME_S = 0.1
FALL_TILT_RAD = 0.3
RECOVERED_M = 0.01


@dataclass(frozen=True)
class StandingKinematics:
    """Per tick, from the measured link angles and the foot sensors: ZMP (ticks x 2, NaN where
    the feet carry nothing), each foot's vertical force (ticks x 2: left, right), pelvis tilt,
    CoM (ticks x 3), the ZMP's margin inside the support polygon (negative: outside), standing
    on the left sole at the origin."""

    zmp_m: np.ndarray
    vertical_n: np.ndarray
    tilt_rad: np.ndarray
    com_m: np.ndarray
    margin_m: np.ndarray
    support_polygon: tuple[float, float, float, float]  # x min, x max, y min, y max

    @classmethod
    def of(cls, run: RunData) -> StandingKinematics:
        from controller.humanoid import FootWrench, NoSupportError, zmp_from_foot_wrenches

        model = leg_model()
        links = np.column_stack(run.per_joint("link_angle_rad"))
        wrench = {
            foot: np.column_stack([run.columns[k] for k in wrench_keys(foot)]) for foot in FEET
        }
        ticks = links.shape[0]
        zmp = np.full((ticks, 2), np.nan)
        vertical = np.zeros((ticks, 2))
        tilt = np.full(ticks, np.nan)
        com = np.full((ticks, 3), np.nan)
        for k in range(ticks):
            if not np.isfinite(links[k]).all():
                continue
            q = model.standing_configuration(links[k], side=0)
            rotation = pelvis_rotation(q)
            tilt[k] = math.acos(max(-1.0, min(1.0, rotation[2, 2])))
            feet = []
            for side, foot in enumerate(FEET):
                w = wrench[foot][k]
                if np.isfinite(w).all():
                    placement = model.ft_sensor_placement(side)
                    feet.append(FootWrench(w[:3], w[3:], placement.translation, placement.rotation))
                    vertical[k, side] = (placement.rotation @ w[:3])[2]
            with contextlib.suppress(NoSupportError, ValueError):
                zmp[k] = zmp_from_foot_wrenches(feet)
            com[k] = model.centre_of_mass(q)
        polygon = _support_polygon(model, links[0])
        x_min, x_max, y_min, y_max = polygon
        margin = np.minimum.reduce(
            [zmp[:, 0] - x_min, x_max - zmp[:, 0], zmp[:, 1] - y_min, y_max - zmp[:, 1]]
        )
        return cls(zmp, vertical, tilt, com, margin, polygon)


def _support_polygon(model: Any, links: np.ndarray) -> tuple[float, float, float, float]:
    """Both soles' bounding box on the ground (standing on the left sole at the origin)."""
    model.standing_configuration(links, side=0)
    corners = []
    for side in (0, 1):
        sole = model.sole_placement(side)
        half = model.sole_boxes[side].size_m / 2.0
        for dx in (-half[0], half[0]):
            for dy in (-half[1], half[1]):
                corners.append(sole.translation + sole.rotation @ np.array([dx, dy, 0.0]))
    points = np.array(corners)
    return (
        float(points[:, 0].min()),
        float(points[:, 0].max()),
        float(points[:, 1].min()),
        float(points[:, 1].max()),
    )


@dataclass(frozen=True)
class HumanoidStandingExperiment(Experiment):
    """Hold a posture in double support (see the module docstring); pushes optional."""

    __test__ = False

    name: str
    title: str
    duration_s: float
    posture_rad: tuple[float, ...]
    world: World = World()

    def reference(self, time_s: float) -> np.ndarray:
        return np.asarray(self.posture_rad)

    def support(self, time_s: float) -> object:
        from controller.humanoid import SupportState

        return SupportState.DOUBLE

    def reaction_policy(self) -> ReactionPolicy:
        """The robot on its feet (legs.py `on_feet`); it stands in double support all along, so
        a `finish_step` holds as soon as the feet are seen to carry it (SETTLE_S at most)."""
        return on_feet(within_s=SETTLE_S)

    def metrics(self, run: RunData) -> dict[str, Any]:
        kinematics = StandingKinematics.of(run)
        settled = run.time_s >= run.experiment_start_s + SETTLE_S
        desired = self._desired_zmp()
        error = np.linalg.norm(kinematics.zmp_m - desired, axis=1)
        deflection = np.abs(np.column_stack(run.per_joint("deflection_rad")))
        metrics = {
            "pelvis_tilt_rad": _max(kinematics.tilt_rad[settled]),
            "max_deflection_rad": _max(deflection[settled]),
            "zmp_max_error_m": _max(error[settled]),
            "zmp_rms_error_m": float(np.sqrt(np.nanmean(error[settled] ** 2)))
            if settled.any()
            else None,
            "fell": _fell(kinematics, run, self._weight_n()),
        }
        if self.world.pelvis_pushes:
            metrics.update(self._push_metrics(run, kinematics))
        return metrics

    def derived_series(self, run: RunData) -> DerivedSeries:
        """kinematics.csv (hil/output/series.py): every log row's ZMP, desired ZMP, CoM,
        pelvis tilt, support margin and the feet's vertical forces, as `metrics` sees them."""
        k = StandingKinematics.of(run)
        return kinematics_series(
            run.columns["tick"], run.time_s, k.zmp_m, self._desired_zmp(), k.com_m,
            k.tilt_rad, k.margin_m, k.vertical_n,
        )  # fmt: skip

    def _push_metrics(self, run: RunData, kinematics: StandingKinematics) -> dict[str, Any]:
        push = self.world.pelvis_pushes[0]
        start = push.start_s + run.experiment_start_s
        before = np.flatnonzero(run.time_s < start)
        if not before.size:
            return {}
        reference = kinematics.zmp_m[before[-1]]
        distance = np.linalg.norm(kinematics.zmp_m - reference, axis=1)
        after = run.time_s >= start
        outside = np.flatnonzero(after & ~(distance <= RECOVERED_M))
        period = float(np.median(np.diff(run.time_s)))
        recovery = float(run.time_s[outside[-1]] + period - start) if outside.size else 0.0
        return {"zmp_excursion_m": _max(distance[after]), "recovery_time_s": recovery}

    @functools.cached_property
    def _desired(self) -> tuple[np.ndarray, float]:
        model = leg_model()
        q = model.standing_configuration(np.asarray(self.posture_rad), side=0)
        return model.centre_of_mass(q)[:2], model.total_mass_kg * 9.81

    def _desired_zmp(self) -> np.ndarray:
        return self._desired[0]

    def _weight_n(self) -> float:
        return self._desired[1]

    def marks(self, run: RunData) -> WorldMarks:
        start = run.experiment_start_s
        return WorldMarks(
            pushes=tuple(
                PushMark(p.start_s + start, p.duration_s, float(np.linalg.norm(p.force_n)))
                for p in self.world.pelvis_pushes
            ),
            title=self.title,
            experiment=self.name,
        )

    @property
    def report_columns(self) -> tuple[Column, ...]:
        return (
            Column("pelvis_tilt_rad", "pelvis tilt [rad]", number(".4f")),
            Column("max_deflection_rad", "max deflection [rad]", number(".4f")),
            Column("zmp_max_error_m", "ZMP max error [m]", number(".4f")),
            Column("zmp_rms_error_m", "ZMP rms error [m]", number(".4f")),
            Column("zmp_excursion_m", "ZMP excursion [m]", number(".4f")),
            Column("recovery_time_s", "recovery [s]", number(".2f")),
            Column("fell", "fell", number("")),
        )

    def relations(self, entries: Sequence[RunEntry]) -> list[Relation]:
        return standing_relations(self.name, entries)

    def comparison_figure(
        self, runs: Sequence[ComparisonRun], path: Path, setup: str
    ) -> Path | None:
        """The measured ZMP (fore-aft, sideways, with the feet's extent) and the pelvis tilt of
        every controller's run over time."""
        if not runs:
            return None
        from matplotlib.figure import Figure

        figure = Figure(figsize=(9.0, 8.0), layout="constrained")
        axes = figure.subplots(3, 1, sharex=True)
        desired = self._desired_zmp()
        for entry in in_drawing_order(runs):
            run = entry.run
            kinematics = StandingKinematics.of(run)
            time_s = run.time_s
            style = entry.style.kwargs()
            axes[0].plot(time_s, kinematics.zmp_m[:, 0], label=entry.label, **style)
            axes[1].plot(time_s, kinematics.zmp_m[:, 1], **style)
            axes[2].plot(time_s, kinematics.tilt_rad, **style)
        polygon = StandingKinematics.of(runs[0].run).support_polygon
        for ax, axis in ((axes[0], 0), (axes[1], 1)):
            ax.axhline(desired[axis], color="k", lw=0.8, ls="--", label="desired (CoM)")
            for edge in polygon[2 * axis : 2 * axis + 2]:
                ax.axhline(edge, color="0.6", lw=0.8, ls=":")
        for ax in axes:
            mark_world(ax, self.marks(runs[0].run))
            ax.grid(True, alpha=0.3)
        axes[0].set_ylabel("ZMP x (forward) [m]")
        axes[1].set_ylabel("ZMP y (left) [m]\n(dotted: the feet)")
        axes[2].set_ylabel("pelvis tilt [rad]")
        axes[2].set_xlabel("time [s]")
        axes[0].legend(fontsize=8, loc="upper right")
        figure.suptitle(comparison_title(self.title, setup))
        return save_figure(figure, path)


def _max(values: np.ndarray) -> float | None:
    finite = np.asarray(values, dtype=float)
    finite = finite[np.isfinite(finite)]
    return float(finite.max()) if finite.size else None


def _fell(kinematics: StandingKinematics, run: RunData, weight_n: float) -> bool:
    outside = ~(kinematics.margin_m >= -FALL_MARGIN_M)  # NaN (no ZMP) counts as outside
    unloaded = kinematics.vertical_n.sum(axis=1) < 0.5 * weight_n
    started = run.time_s >= run.experiment_start_s + SETTLE_S
    period = float(np.median(np.diff(run.time_s))) if run.time_s.size > 1 else 0.005
    window = max(1, round(FALL_TIME_S / period))
    for bad in (outside & started, unloaded & started):
        runs = np.convolve(bad.astype(int), np.ones(window, dtype=int), mode="valid")
        if runs.size and runs.max() >= window:
            return True
    tilted = kinematics.tilt_rad[started]
    return bool(np.any(tilted[np.isfinite(tilted)] > FALL_TILT_RAD))


def standing_relations(exp: str, entries: Sequence[RunEntry]) -> list[Relation]:
    """What the paper says of standing on flexible joints (Sec. III-A, IV-C): the gravity
    compensator keeps the posture the legs' springs would otherwise give away."""
    gc = find(entries, exp, ControllerKind.GC)
    pid = find(entries, exp, ControllerKind.PID)

    def gc_helps() -> tuple[bool, str]:
        with_gc = metric(gc, "zmp_max_error_m", "gc")
        without = metric(pid, "zmp_max_error_m", "pid")
        tilt_gc = metric(gc, "pelvis_tilt_rad", "gc")
        tilt_pid = metric(pid, "pelvis_tilt_rad", "pid")
        return tilt_gc <= tilt_pid, (
            f"tilt {tilt_gc:.4f} vs {tilt_pid:.4f} rad, ZMP error {with_gc * 1e3:.1f} vs "
            f"{without * 1e3:.1f} mm"
        )

    def stands(kind: ControllerKind) -> Callable[[], tuple[bool, str]]:
        def test() -> tuple[bool, str]:
            entry = find(entries, exp, kind)
            if entry is None:
                raise Missing(f"no {kind} run")
            rms = metric(entry, "zmp_rms_error_m", str(kind))
            return entry.result.ok, f"{entry.result.ending}, ZMP rms error {rms * 1e3:.1f} mm"

        return test

    return [
        check(
            exp,
            "the gravity compensator keeps the pelvis more upright than position control alone",
            "GC makes the joints hold the desired angles under gravity (Sec. III-A)",
            gc_helps,
        ),
        *(
            check(
                exp,
                f"{kind} holds the robot standing to the end, without a safety stop",
                "the paper walks DYROS-JET with GC+LQR and GC+LQR+DOB (Sec. IV-C, Fig. 7): "
                "standing comes first",
                stands(kind),
            )
            for kind in (ControllerKind.GC_LQR, ControllerKind.GC_LQR_DOB)
        ),
    ]


# The lab's knee servo and the walking-ready posture (controller/humanoid/posture.py).
def _walking_ready() -> tuple[float, ...]:
    from controller.humanoid import WALKING_READY_LEG_ANGLES_RAD

    return tuple(WALKING_READY_LEG_ANGLES_RAD)


STAND = HumanoidStandingExperiment(
    name="stand",
    title="DYROS-JET stands in the walking-ready posture (double support)",
    duration_s=4.0,
    posture_rad=_walking_ready(),
)

# A push on the pelvis while standing: 60 N forward for 0.2 s (12 N s; the paper pushes the
# testbed, not the robot: the figures are this experiment's, chosen to move the ZMP a few cm).
PUSH = HumanoidStandingExperiment(
    name="push",
    title="DYROS-JET standing, pushed at the pelvis (60 N forward, 0.2 s)",
    duration_s=4.0,
    posture_rad=_walking_ready(),
    world=World(pelvis_pushes=(PelvisPush(start_s=2.0, duration_s=0.2, force_n=(60.0, 0, 0)),)),
)
