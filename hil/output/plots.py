"""Figures: one run's signals (`plot_run`) and the pieces the experiments' comparison figures use.

Everything is drawn on matplotlib's Agg canvas through `matplotlib.figure.Figure`, never through
`pyplot`: no display is needed, no global figure state is kept, and a figure is freed as soon as
it is saved.

One run (`plot_run`, after every `hil run`): `plot.png` in the run directory (`plot-NAME.png`
per joint when there are several), three panels on one time axis:
    1. link angle and its reference, motor angle and the goal sent to the actuator [rad]
       (with an obstacle: the block's angle as a horizontal line)
    2. motor current [A] with the actuator's current limit (and the software guard's threshold
       when the guard is on)
    3. contact force [N] (experiments with an obstacle) or gear deflection link - motor [rad]
On every panel: the supervisor's events (safety stops, torque off) as vertical lines, torque-off
stretches shaded, pushes shaded, the first contact and the actuator's overload marked.

Comparison figures (the paper's Figs. 5 and 6) live with their experiments
(`hil.experiments.contact`, `hil.experiments.impact`); they draw with `comparison_style`, the
paper's line styles: PID blue dotted, GC+LQR+DOB with Kdist = 1 red dash-dot, with Kdist = 0.5
green dashed; the other controllers (GC, GC+LQR) thinner and lighter.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from drivers.joint_bus import ActuatorFault
from hil.output.rundir import RunData
from hil.vocabulary import ControllerChoice, ControllerKind

if TYPE_CHECKING:  # matplotlib is imported where a figure is drawn: a run that plots nothing,
    # and `hil emulate`, do not pay for it
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

DPI = 110
# Events that are routine bookkeeping, not something that happened to the robot.
_ROUTINE_EVENTS = frozenset(
    {
        "open",
        "torque_on",
        "close_failed",
        "exit_hold",
        # tolerated glitches and limiter notices: up to 20 of each would clutter the plot
        "bus_glitch",
        "link_glitch",
        "bus_recovered",
        "link_recovered",
        "goal_limited",
    }
)


@dataclass(frozen=True)
class Push:
    """A push drawn as a shaded span (loop time)."""

    start_s: float
    duration_s: float
    force_n: float


@dataclass(frozen=True)
class WorldMarks:
    """What the experiment's world did, for the plots (loop time, after any re-homing)."""

    pushes: tuple[Push, ...] = ()
    obstacle_angle_rad: float | None = None
    contact_time_s: float | None = None
    title: str = ""
    experiment: str = ""


@dataclass(frozen=True)
class RunPlotSettings:
    """Figures of the run that are not in its log: current limits and the guard's fraction."""

    current_limits_a: Sequence[float] = field(default_factory=list)
    guard_fraction: float | None = None

    @classmethod
    def of(cls, run: RunData) -> RunPlotSettings:
        limits = [
            math.nan if v is None else float(v) for v in run.summary.get("current_limit_a") or []
        ]
        safety = run.meta.get("config", {}).get("safety", {})
        fraction = safety.get("current_guard_fraction") if safety.get("current_guard") else None
        return cls(limits or [math.nan], fraction)


def first_time(time_s: np.ndarray, mask: np.ndarray) -> float | None:
    index = np.flatnonzero(mask)
    return float(time_s[index[0]]) if index.size else None


def overload_time_s(run: RunData, joint: str = "") -> float | None:
    """First tick the actuator reports an overload (ActuatorFault.OVERLOAD in actuator_fault)."""
    flags = run.signal("actuator_fault", joint).astype(int)
    return first_time(run.time_s, (flags & ActuatorFault.OVERLOAD) != 0)


def save_figure(figure: Figure, path: Path, dpi: int = DPI) -> Path:
    """The figure as a PNG; a disk that did not take it whole leaves no half file (the OSError
    goes on: the caller says the figure is missing)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(figure)
    try:
        figure.savefig(path, dpi=dpi)
    except OSError:
        Path(path).unlink(missing_ok=True)
        raise
    return path


# --- one run ----------------------------------------------------------------------------------
def plot_run(run: RunData, marks: WorldMarks) -> list[Path]:
    """Draw one run's PNG(s) into its directory; returns the files written."""
    settings = RunPlotSettings.of(run)
    limits = list(settings.current_limits_a)
    paths = []
    for index, joint in enumerate(run.joint_names):
        limit = limits[index] if index < len(limits) else limits[0]
        name = "plot.png" if len(run.joint_names) == 1 else f"plot-{joint}.png"
        figure = _run_figure(run, marks, joint, limit, settings.guard_fraction)
        paths.append(save_figure(figure, run.out_dir / name))
    return paths


def _run_figure(
    run: RunData, marks: WorldMarks, joint: str, current_limit: float, guard: float | None
) -> Figure:
    from matplotlib.figure import Figure

    time = run.time_s
    # Fixed margins, not layout="constrained": a run's figure is drawn after every run (twelve
    # on the humanoid), and the constrained layout measures every text twice (~60 % of the
    # drawing time, measured); the panels and titles here fit the margins below.
    figure = Figure(figsize=(10, 9))
    figure.subplots_adjust(left=0.08, right=0.98, top=0.90, bottom=0.06, hspace=0.12)
    angle_ax, current_ax, third_ax = figure.subplots(3, 1, sharex=True)
    joint_note = f", joint {joint}" if joint else ""
    setup = run.meta.get("setup", "")
    figure.suptitle(
        f"{marks.experiment}: {run.label}{joint_note}"
        + (f" on the {setup}" if setup else "")
        + f"\n{marks.title}\nended: {run.termination}",
        fontsize=10,
    )
    _angles_panel(angle_ax, run, marks, joint)
    _current_panel(current_ax, run, joint, current_limit, guard)
    if marks.obstacle_angle_rad is not None and "contact_force_n" in run.columns:
        third_ax.plot(
            time, run.columns["contact_force_n"], color="tab:brown", label="contact force"
        )
        third_ax.set_ylabel("contact force [N]")
    else:
        deflection = run.signal("deflection_rad", joint)
        third_ax.plot(time, deflection, color="tab:cyan", label="deflection (link - motor)")
        third_ax.set_ylabel("deflection [rad]")
    third_ax.set_xlabel("time [s]")
    for ax in (angle_ax, current_ax, third_ax):
        mark_world(ax, marks)
        mark_torque_off(ax, time, run.signal("torque_enabled", joint))
        mark_events(ax, run.events, float(time[-1]), label_them=ax is angle_ax)
        ax.grid(True, alpha=0.3)
        # a fixed corner: loc="best" tests every data point against every spot (~0.3 s a
        # figure on a long run)
        ax.legend(loc="upper right", fontsize=8)
    return figure


def _angles_panel(ax: Axes, run: RunData, marks: WorldMarks, joint: str) -> None:
    time = run.time_s
    ax.plot(time, run.signal("reference_rad", joint), "k-", lw=1.0, label="link reference")
    ax.plot(time, run.signal("link_angle_rad", joint), color="tab:blue", label="link angle")
    ax.plot(time, run.signal("motor_angle_rad", joint), color="tab:orange", label="motor angle")
    ax.plot(time, run.signal("goal_rad", joint), color="tab:green", ls="--", lw=1.0, label="goal")
    if marks.obstacle_angle_rad is not None:
        ax.axhline(marks.obstacle_angle_rad, color="tab:brown", ls=":", lw=1.0, label="block")
    ax.set_ylabel("angle [rad]")


def _current_panel(
    ax: Axes, run: RunData, joint: str, current_limit: float, guard: float | None
) -> None:
    time = run.time_s
    current = run.signal("motor_current_a", joint)
    ax.plot(time, current, color="tab:purple", lw=1.0, label="motor current")
    for sign in (1.0, -1.0):
        ax.axhline(
            sign * current_limit,
            color="tab:red",
            ls="--",
            lw=1.0,
            label=f"current limit ±{current_limit:.2f} A" if sign > 0 else None,
        )
        if guard:
            ax.axhline(
                sign * guard * current_limit,
                color="tab:red",
                ls=":",
                lw=0.8,
                label=f"software guard {guard:.0%}" if sign > 0 else None,
            )
    trip = overload_time_s(run, joint)
    if trip is not None:
        index = max(int(np.searchsorted(time, trip)) - 1, 0)  # the current as it tripped
        ax.plot(trip, current[index], "X", color="tab:red", ms=9, label=f"overload at {trip:.3f} s")
    ax.set_ylabel("motor current [A]")


def mark_world(ax: Axes, marks: WorldMarks) -> None:
    for number, push in enumerate(marks.pushes):
        ax.axvspan(
            push.start_s,
            push.start_s + push.duration_s,
            color="tab:red",
            alpha=0.25,
            label=f"push {abs(push.force_n):g} N" if number == 0 else None,
        )
    if marks.contact_time_s is not None:
        contact = marks.contact_time_s
        ax.axvline(contact, color="tab:brown", ls="-.", lw=1.0, label=f"contact at {contact:.3f} s")


def torque_off_spans(time_s: np.ndarray, torque_on: np.ndarray) -> list[tuple[float, float]]:
    """Stretches with torque off after start-up (the first tick's sample predates the enable)."""
    off = torque_on < 0.5
    off[:2] = False
    spans = []
    period = float(np.median(np.diff(time_s))) if time_s.size > 1 else 0.005
    edges = np.flatnonzero(np.diff(off.astype(int)))
    starts = [i + 1 for i in edges if not off[i]]
    ends = [i + 1 for i in edges if off[i]]
    for start in starts:
        end = next((e for e in ends if e > start), len(off))
        spans.append((float(time_s[start]), float(time_s[end - 1]) + period))
    return spans


def mark_torque_off(ax: Axes, time: np.ndarray, torque_on: np.ndarray) -> None:
    for number, (start, end) in enumerate(torque_off_spans(time, torque_on)):
        ax.axvspan(start, end, color="0.5", alpha=0.15, label="torque off" if number == 0 else None)


def mark_events(
    ax: Axes, events: Sequence[dict[str, Any]], end_s: float, *, label_them: bool
) -> None:
    """Events inside the logged run, one line and one label per instant (exit bookkeeping
    after the last row is left out)."""
    at: dict[float, list[dict[str, Any]]] = {}
    for event in events:
        when = float(event.get("time_s", math.nan))
        if str(event.get("kind", "")) in _ROUTINE_EVENTS or not 0.0 < when <= end_s:
            continue
        at.setdefault(when, []).append(event)
    for when, group in at.items():
        safety = any("action" in e for e in group)
        color = "tab:red" if safety else "0.2"
        ax.axvline(when, color=color, ls="-" if safety else "--", lw=1.0)
        if label_them:
            text = "; ".join(
                f"{e['kind']} -> {e['action']}" if "action" in e else str(e["kind"]) for e in group
            )
            ax.annotate(
                f"{text} ({when:.3f} s)",
                xy=(when, 1.0),
                xycoords=("data", "axes fraction"),
                xytext=(3, -3),
                textcoords="offset points",
                rotation=90,
                va="top",
                fontsize=7,
                color=color,
            )


# --- comparison figures ------------------------------------------------------------------------
@dataclass(frozen=True)
class LineStyle:
    color: str
    linestyle: str
    linewidth: float
    alpha: float
    highlighted: bool

    def kwargs(self) -> dict[str, Any]:
        return {
            "color": self.color,
            "linestyle": self.linestyle,
            "linewidth": self.linewidth,
            "alpha": self.alpha,
            "zorder": 3 if self.highlighted else 2,
        }


def comparison_style(choice: ControllerChoice) -> LineStyle:
    """The paper's styles (Figs. 5, 6) for PID and GC+LQR+DOB; the others lighter."""
    if choice.kind is ControllerKind.PID:
        return LineStyle("tab:blue", ":", 2.0, 1.0, True)
    if choice.kind is ControllerKind.GC_LQR_DOB:
        if choice.reading is not None:  # the other reading of (25)
            return LineStyle("tab:brown", "-", 1.2, 0.8, False)
        if math.isclose(choice.kdist, 1.0):
            return LineStyle("tab:red", "-.", 1.8, 1.0, True)
        if math.isclose(choice.kdist, 0.5):
            return LineStyle("tab:green", "--", 1.8, 1.0, True)
        return LineStyle("tab:purple", "--", 1.5, 1.0, True)
    if choice.kind is ControllerKind.GC_LQR:
        return LineStyle("tab:orange", "-", 1.0, 0.5, False)
    return LineStyle("0.45", "-", 1.0, 0.5, False)


@dataclass(frozen=True)
class ComparisonRun:
    """One run in a comparison figure: its controller and its data; `name` and `line` when the
    legend and the line are not the controller's (`hil compare`: two runs of one controller)."""

    choice: ControllerChoice
    run: RunData
    name: str | None = None
    line: LineStyle | None = None

    @property
    def label(self) -> str:
        return self.name if self.name is not None else self.choice.label

    @property
    def style(self) -> LineStyle:
        return self.line if self.line is not None else comparison_style(self.choice)


def in_drawing_order(runs: Sequence[ComparisonRun]) -> list[ComparisonRun]:
    """Highlighted runs drawn last (on top)."""
    return sorted(runs, key=lambda r: r.style.highlighted)


def comparison_title(title: str, setup: str) -> str:
    where = f" on the {setup}" if setup else ""
    return f"{title}\nKim et al., ICRA 2018, reproduced{where}"
