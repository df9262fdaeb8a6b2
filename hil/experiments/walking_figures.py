"""The walking experiments' figures (Kim et al., ICRA 2018, Figs. 7 and 8), from the runs' logs.

    lateral_zmp_figure     Fig. 7: desired and measured lateral ZMP over time, one panel per
                           controller, the planted feet's lateral extent as boxes
    step_sequence_figure   Fig. 8: the legs drawn from the measured link angles (side view) at
                           moments around the step onto the object, one row per controller, and
                           the lateral ZMP of every controller below

Everything drawn is what the robot's own sensors report (`WalkingKinematics`): no simulator
state, no GL (matplotlib only).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hil.experiments.legs import anchor_feet, leg_model, placed_configuration
from hil.experiments.walking_kinematics import WalkingKinematics, stopped_at_s
from hil.output.plots import ComparisonRun, comparison_title, save_figure
from hil.vocabulary import ControllerKind

FOOT_COLOUR = "#9b59b6"  # the paper's purple foot placements
LEG_COLOURS = ("tab:blue", "tab:red")  # left, right
N_FRAMES = 8
LEG_CHAIN = ("HipRoll", "KneePitch", "AnkleRoll")
ZMP_AXIS_M = (-0.35, 0.35)  # the feet and a margin: a fallen robot's estimate leaves the plot


def _planted_intervals(experiment: Any) -> list[tuple[int, float, float, Any]]:
    """(side, start [s], end [s], footstep) for every placement a foot keeps on the ground."""
    from controller.walking import SegmentKind

    pattern = experiment.pattern
    timeline = pattern.timeline
    dt = pattern.dt_s
    end_s = timeline.n_ticks * dt
    plan = experiment.plan
    placed = {0: (0.0, plan.initial_left), 1: (0.0, plan.initial_right)}
    intervals = []
    for segment in timeline.segments:
        if segment.kind is not SegmentKind.SINGLE_SUPPORT:
            continue
        side = segment.landing_side.index
        since, step = placed[side]
        intervals.append((side, since, segment.start_tick * dt, step))
        placed[side] = (segment.end_tick * dt, plan.footsteps[segment.footstep_index])
    for side, (since, step) in placed.items():
        intervals.append((side, since, end_s, step))
    return intervals


def _draw_feet(ax: Any, experiment: Any) -> None:
    from matplotlib.patches import Rectangle

    from controller.walking.dyros_jet_figures import FOOT_WIDTH_M

    for _side, start, end, step in _planted_intervals(experiment):
        ax.add_patch(
            Rectangle(
                (start, step.y_m - FOOT_WIDTH_M / 2),
                end - start,
                FOOT_WIDTH_M,
                facecolor=FOOT_COLOUR,
                alpha=0.15,
                edgecolor=FOOT_COLOUR,
                lw=0.8,
            )
        )


def lateral_zmp_figure(
    experiment: Any, runs: Sequence[ComparisonRun], path: Path, setup: str
) -> Path:
    """Fig. 7: per controller, the desired and the measured lateral ZMP, with the feet."""
    from matplotlib.figure import Figure

    ordered = sorted(runs, key=lambda r: r.choice.name)
    figure = Figure(figsize=(9.0, 2.1 * len(ordered) + 1.0), layout="constrained")
    axes = np.atleast_1d(figure.subplots(len(ordered), 1, sharex=True, sharey=True))
    pattern = experiment.pattern
    for ax, entry in zip(axes, _paper_order(ordered), strict=True):
        kinematics = WalkingKinematics.of(entry.run, experiment)
        _draw_feet(ax, experiment)
        ax.plot(pattern.time_s, pattern.zmp_reference_m[:, 1], "k--", lw=1.0, label="desired")
        style = entry.style.kwargs()
        style["linestyle"] = "-"
        ax.plot(kinematics.time_s, kinematics.zmp_m[:, 1], label="measured", **style)
        ax.set_ylim(*ZMP_AXIS_M)
        _mark_fall(ax, entry, kinematics)
        ax.set_ylabel(f"{walking_label(entry)}\nZMP y [m]", fontsize=8)
        ax.grid(True, alpha=0.3)
        ax.set_xlim(0.0, pattern.time_s[-1])
        ax.legend(fontsize=7, loc="upper right")
    axes[-1].set_xlabel("time [s] (from the start of the walk's pattern)")
    figure.suptitle(
        comparison_title(f"{experiment.title}\ndesired and measured lateral ZMP", setup)
        + "\n(purple: the feet on the ground)",
        fontsize=9,
    )
    return save_figure(figure, path)


def walking_label(entry: ComparisonRun) -> str:
    """The run's controller as the walks name it: `pid` with the lab's position-mode terms is
    the paper's default controller (the actuator's own position control with the lab's
    walking scheme, hil/experiments/walking_scheme.py); the scheme's terms come from the run's
    summary.json."""
    scheme = str(entry.run.summary.get("reference_feedback") or "")
    if entry.choice.kind is ControllerKind.PID and "deflection model" in scheme:
        return "default (pid + the lab's scheme)"
    return entry.label


def _paper_order(runs: Sequence[ComparisonRun]) -> list[ComparisonRun]:
    order = {"pid": 0, "gc": 1, "gc+lqr": 2, "gc+lqr+dob": 3}
    return sorted(runs, key=lambda r: order.get(r.choice.name, 9))


def _mark_fall(ax: Any, entry: ComparisonRun, kinematics: WalkingKinematics) -> None:
    """The fall (red) and the safety stop (black) on a time axis."""
    for when, what, colour in (
        (kinematics.fall_time_s(), "fell", "r"),
        (stopped_at_s(entry.run), "safety stop", "k"),
    ):
        if when is not None:
            ax.axvline(when, color=colour, lw=0.8, ls=":")
            ax.text(when, ax.get_ylim()[1], f" {what}", color=colour, va="top", fontsize=7)


def _row_label(entry: ComparisonRun, kinematics: Any) -> str:
    label = walking_label(entry).replace(" (", "\n(")
    fell, stopped = kinematics.fall_time_s(), stopped_at_s(entry.run)
    if stopped is not None:
        label += f"\nstop {stopped:.2f} s"
    if fell is not None:
        label += f"\nfell {fell:.2f} s"
    return label


def _frame_times(experiment: Any) -> np.ndarray:
    """N_FRAMES moments from the object footstep's lift-off to the end of the next step."""
    timeline = experiment.pattern.timeline
    dt = experiment.pattern.dt_s
    singles = [s for s in timeline.segments if s.kind.value == "single_support"]
    index = experiment.object_footstep
    start = singles[index].start_tick * dt
    end = singles[min(index + 1, len(singles) - 1)].end_tick * dt + 0.3
    return np.linspace(start, end, N_FRAMES)


def _leg_points(model: Any, side: int) -> np.ndarray:
    """Pelvis, hip, knee, ankle and sole centre of one leg (world, after a kinematics update)."""
    from controller.humanoid import LEG_JOINT_NAMES

    prefix = LEG_JOINT_NAMES[6 * side][:2]
    points = [model.data.oMi[1].translation]
    for name in LEG_CHAIN:
        points.append(model.data.oMi[model.model.getJointId(prefix + name)].translation)
    points.append(model.sole_placement(side).translation)
    return np.array(points)


def _draw_frame(
    ax: Any, experiment: Any, kinematics: Any, time_s: float, anchors: np.ndarray
) -> None:
    """One moment of Fig. 8: the box, the ground and both legs (side view) from the link
    angles logged nearest `time_s`, or "stopped" when the log has none."""
    from matplotlib.patches import Rectangle

    model = leg_model()
    pattern = experiment.pattern
    half_length = model.sole_boxes[0].size_m[0] / 2.0
    for box in experiment.world.floor_objects:
        ax.add_patch(
            Rectangle(
                (box.centre_m[0] - box.size_m[0] / 2, 0.0),
                box.size_m[0],
                box.height_m,
                color="0.5",
            )
        )
    ax.axhline(0.0, color="k", lw=0.8)
    rows = np.flatnonzero(np.abs(kinematics.time_s - time_s) < 0.5 * kinematics.period_s)
    if rows.size and np.isfinite(kinematics.links_rad[rows[0]]).all():
        tick = min(pattern.n_ticks - 1, int(round(time_s / pattern.dt_s)))
        placed_configuration(
            model, kinematics.links_rad[rows[0]], int(anchors[tick]), pattern, tick
        )
        for side in (1, 0):  # the left leg on top
            points = _leg_points(model, side)
            ax.plot(points[:, 0], points[:, 2], "-o", color=LEG_COLOURS[side], ms=2, lw=1.5)
            sole = points[-1]
            ax.plot(
                [sole[0] - half_length, sole[0] + half_length],
                [sole[2], sole[2]],
                color=LEG_COLOURS[side],
                lw=2.5,
            )
    else:
        ax.text(0.5, 0.5, "stopped", transform=ax.transAxes, ha="center", fontsize=7)
    ax.set_xlim(0.05, 0.95)
    ax.set_ylim(-0.03, 0.95)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])


def step_sequence_figure(
    experiment: Any, runs: Sequence[ComparisonRun], path: Path, setup: str
) -> Path:
    """Fig. 8: stick figures (side view) of every controller's legs around the object step."""
    from matplotlib.figure import Figure

    ordered = _paper_order(runs)
    pattern = experiment.pattern
    anchors = anchor_feet(pattern)
    times = _frame_times(experiment)
    figure = Figure(figsize=(1.5 * N_FRAMES + 1.0, 2.3 * len(ordered) + 2.6), layout="constrained")
    grid = figure.add_gridspec(len(ordered) + 1, N_FRAMES, height_ratios=[1] * len(ordered) + [1.1])
    zmp_ax = figure.add_subplot(grid[len(ordered), :])
    _draw_feet(zmp_ax, experiment)
    zmp_ax.plot(pattern.time_s, pattern.zmp_reference_m[:, 1], "k--", lw=1.0, label="desired")
    for row, entry in enumerate(ordered):
        kinematics = WalkingKinematics.of(entry.run, experiment)
        style = entry.style.kwargs()
        style["linestyle"] = "-"
        zmp_ax.plot(kinematics.time_s, kinematics.zmp_m[:, 1], label=walking_label(entry), **style)
        for column, time_s in enumerate(times):
            ax = figure.add_subplot(grid[row, column])
            _draw_frame(ax, experiment, kinematics, float(time_s), anchors)
            if row == 0:
                ax.set_title(f"{time_s:.2f} s", fontsize=7)
            if column == 0:
                ax.set_ylabel(_row_label(entry, kinematics), fontsize=7)
    zmp_ax.set_xlabel("time [s]")
    zmp_ax.set_ylabel("ZMP y [m]")
    zmp_ax.set_ylim(*ZMP_AXIS_M)
    zmp_ax.grid(True, alpha=0.3)
    zmp_ax.set_xlim(0.0, pattern.time_s[-1])
    zmp_ax.legend(fontsize=7, loc="upper right", ncol=5)
    for t in times:
        zmp_ax.axvline(t, color="0.7", lw=0.5)
    figure.suptitle(
        comparison_title(
            f"{experiment.title}\nthe legs from the measured link angles (side view; blue left, "
            "red right, grey the box), and the lateral ZMP",
            setup,
        ),
        fontsize=9,
    )
    return save_figure(figure, path)
