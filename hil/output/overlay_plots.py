"""The figures of `hil compare`: any runs of one experiment overlaid, one line per run, in the
style of a run's own plot (hil/output/plots.py) and of the experiments' comparison figures.

    signals.png        (signals-JOINT.png per joint, up to MAX_JOINT_FIGURES joints) link angle
                       and the reference, motor current, and the contact force
                       (runs that log one) or the gear deflection
    joints.png         (more joints: the humanoid) per joint, the tracking error link -
                       reference and the gear deflection
    kinematics.png     (runs with kinematics.csv: the humanoid) the measured and the desired ZMP
                       fore-aft and sideways, the pelvis tilt, the ZMP's margin inside the
                       support polygon

What the runs were asked to follow (reference, desired ZMP) is one black line when it is the
same for all, else a thin line in each run's colour. Each run's first safety stop is a
vertical dotted line in its colour. A run that lacks a signal
is left out of that panel and said in the problems returned beside the figures.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from hil.output.plots import LineStyle, save_figure
from hil.output.run_data import Run

if TYPE_CHECKING:
    from matplotlib.axes import Axes

MAX_JOINT_FIGURES = 3


@dataclass(frozen=True)
class OverlayRun:
    """One run in the overlays: its data, its legend and its line."""

    run: Run
    label: str
    style: LineStyle


@dataclass
class Figures:
    """What was drawn, and what could not be."""

    paths: list[Path]
    problems: list[str]


def overlay_figures(runs: Sequence[OverlayRun], out_dir: Path, title: str) -> Figures:
    """Every overlay of the module docstring that these runs have data for, into `out_dir`."""
    figures = Figures([], [])
    joints = list(dict.fromkeys(joint for entry in runs for joint in entry.run.joints))
    if len(joints) <= MAX_JOINT_FIGURES:
        for joint in joints:
            name = "signals.png" if len(joints) == 1 else f"signals-{joint}.png"
            figures.paths.append(_signals_figure(runs, joint, out_dir / name, title, figures))
    else:
        figures.paths.append(_joints_figure(runs, joints, out_dir / "joints.png", title, figures))
    with_kinematics = [entry for entry in runs if entry.run.kinematics is not None]
    if with_kinematics:
        figures.problems += [
            f"{entry.label}: no kinematics.csv (not in kinematics.png)"
            for entry in runs
            if entry.run.kinematics is None
        ]
        figures.paths.append(_kinematics_figure(with_kinematics, out_dir / "kinematics.png", title))
    return figures


def _signal(entry: OverlayRun, name: str, joint: str | None, figures: Figures) -> np.ndarray | None:
    """A run's signal, or None (and a problem said once) when its log has none."""
    run = entry.run
    if joint is not None and joint not in run.joints:
        _problem(figures, f"{entry.label}: no joint {joint}")
        return None
    try:
        return np.asarray(run.signal(name, joint), dtype=float)
    except KeyError:
        where = f"{name}[{joint}]" if joint and len(run.joints) > 1 else name
        _problem(figures, f"{entry.label}: its log has no {where}")
        return None


def _problem(figures: Figures, text: str) -> None:
    if text not in figures.problems:
        figures.problems.append(text)


def _signals_figure(
    runs: Sequence[OverlayRun], joint: str, path: Path, title: str, figures: Figures
) -> Path:
    from matplotlib.figure import Figure

    figure = Figure(figsize=(10, 9))
    figure.subplots_adjust(left=0.08, right=0.98, top=0.90, bottom=0.06, hspace=0.12)
    angle_ax, current_ax, third_ax = figure.subplots(3, 1, sharex=True)
    joint_note = f", joint {joint}" if len(runs[0].run.joints) > 1 else ""
    figure.suptitle(f"{title}{joint_note}\n{len(runs)} runs overlaid", fontsize=10)
    forces = all("contact_force_n" in entry.run.run_signals for entry in runs)
    third_signal = ("contact_force_n", None) if forces else ("deflection_rad", joint)
    references = []
    for entry in runs:
        time, style = entry.run.time_s, entry.style.kwargs()
        link = _signal(entry, "link_angle_rad", joint, figures)
        if link is not None:
            angle_ax.plot(time, link, label=entry.label, **style)
        references.append((entry, time, _signal(entry, "reference_rad", joint, figures)))
        current = _signal(entry, "motor_current_a", joint, figures)
        if current is not None:
            current_ax.plot(time, current, **style)
        third = _signal(entry, *third_signal, figures)
        if third is not None:
            third_ax.plot(time, third, **style)
    _draw_desired(angle_ax, references, "reference")
    angle_ax.set_ylabel("link angle [rad]")
    current_ax.set_ylabel("motor current [A]")
    third_ax.set_ylabel("contact force [N]" if forces else "deflection (link - motor) [rad]")
    third_ax.set_xlabel("time [s]")
    _finish(runs, (angle_ax, current_ax, third_ax))
    return save_figure(figure, path)


def _joints_figure(
    runs: Sequence[OverlayRun], joints: Sequence[str], path: Path, title: str, figures: Figures
) -> Path:
    from matplotlib.figure import Figure

    columns = 4
    rows = math.ceil(len(joints) / columns)
    figure = Figure(figsize=(16, 2.2 * 2 * rows + 1.0))
    figure.subplots_adjust(left=0.05, right=0.99, top=0.93, bottom=0.04, hspace=0.45, wspace=0.3)
    axes = figure.subplots(2 * rows, columns, sharex=True, squeeze=False)
    figure.suptitle(
        f"{title}\n{len(runs)} runs overlaid: tracking error link - reference (upper rows) and "
        "gear deflection link - motor (lower rows) per joint [rad]",
        fontsize=10,
    )
    for index, joint in enumerate(joints):
        row, column = divmod(index, columns)
        error_ax, deflection_ax = axes[2 * row, column], axes[2 * row + 1, column]
        for entry in runs:
            style = entry.style.kwargs()
            link = _signal(entry, "link_angle_rad", joint, figures)
            reference = _signal(entry, "reference_rad", joint, figures)
            if link is not None and reference is not None:
                error_ax.plot(entry.run.time_s, link - reference, label=entry.label, **style)
            deflection = _signal(entry, "deflection_rad", joint, figures)
            if deflection is not None:
                deflection_ax.plot(entry.run.time_s, deflection, **style)
        error_ax.set_title(f"{joint}: error", fontsize=8)
        deflection_ax.set_title(f"{joint}: deflection", fontsize=8)
    for ax in axes.flat:
        ax.grid(True, alpha=0.3)
        ax.tick_params(labelsize=7)
        _mark_stops(ax, runs, labelled=ax is axes[0, 0])
    for ax in axes[-1]:
        ax.set_xlabel("time [s]", fontsize=8)
    axes[0, 0].legend(loc="upper right", fontsize=7)
    return save_figure(figure, path)


def _kinematics_figure(runs: Sequence[OverlayRun], path: Path, title: str) -> Path:
    from matplotlib.figure import Figure

    figure = Figure(figsize=(10, 10))
    figure.subplots_adjust(left=0.1, right=0.98, top=0.91, bottom=0.05, hspace=0.12)
    axes = figure.subplots(4, 1, sharex=True)
    figure.suptitle(
        f"{title}\n{len(runs)} runs overlaid: the ZMP measured and desired, the pelvis tilt, "
        "the support margin (kinematics.csv)",
        fontsize=10,
    )
    desired: dict[str, list[tuple[OverlayRun, np.ndarray, np.ndarray | None]]] = {"x": [], "y": []}
    for entry in runs:
        kinematics = entry.run.kinematics
        assert kinematics is not None  # (only runs that have it)
        time, style = kinematics["time_s"], entry.style.kwargs()
        for ax, axis in ((axes[0], "x"), (axes[1], "y")):
            ax.plot(time, kinematics[f"zmp_{axis}_m"], label=entry.label, **style)
            desired[axis].append((entry, time, kinematics[f"desired_zmp_{axis}_m"]))
        axes[2].plot(time, kinematics["pelvis_tilt_rad"], **style)
        axes[3].plot(time, kinematics["support_margin_m"], **style)
    _draw_desired(axes[0], desired["x"], "desired")
    _draw_desired(axes[1], desired["y"], "desired")
    axes[3].axhline(0.0, color="k", lw=0.8, ls=":")
    axes[0].set_ylabel("ZMP x (forward) [m]")
    axes[1].set_ylabel("ZMP y (left) [m]")
    axes[2].set_ylabel("pelvis tilt [rad]")
    axes[3].set_ylabel("support margin [m]\n(< 0: ZMP outside)")
    axes[3].set_xlabel("time [s]")
    _finish(runs, axes)
    return save_figure(figure, path)


def _draw_desired(
    ax: Axes, lines: Sequence[tuple[OverlayRun, np.ndarray, np.ndarray | None]], name: str
) -> None:
    """What the runs were asked to follow: one black line when it is the same for every run
    (as in the paper's figures), else a thin line in each run's colour."""
    drawn = [(entry, time, values) for entry, time, values in lines if values is not None]
    if not drawn:
        return
    _, first_time, first = drawn[0]
    if all(np.array_equal(values, first, equal_nan=True) for _, _, values in drawn):
        ax.plot(first_time, first, color="k", lw=0.9, label=name, zorder=4)
        return
    for number, (entry, time, values) in enumerate(drawn):
        label = f"{name} (thin)" if number == 0 else None
        ax.plot(time, values, color=entry.style.color, lw=0.7, alpha=0.7, label=label)


def _finish(runs: Sequence[OverlayRun], axes: Sequence[Axes]) -> None:
    for ax in axes:
        ax.grid(True, alpha=0.3)
        _mark_stops(ax, runs, labelled=ax is axes[0])
    axes[0].legend(loc="upper right", fontsize=8)


def _mark_stops(ax: Axes, runs: Sequence[OverlayRun], *, labelled: bool = False) -> None:
    """Each run's first safety stop: a dotted line in its colour (`labelled`: in the legend)."""
    for entry in runs:
        events = entry.run.safety_events
        if events and "time_s" in events[0]:
            first = events[0]
            label = f"{entry.label}: {first.get('cause')} -> {first.get('action')}"
            ax.axvline(
                float(first["time_s"]), color=entry.style.color, ls=":", lw=1.2,
                label=label if labelled else None,
            )  # fmt: skip
