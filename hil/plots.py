"""Figures: one run's signals (`plot_run`) and the paper-style comparisons of Figs. 5 and 6.

Everything is drawn on matplotlib's Agg canvas through `matplotlib.figure.Figure`, never through
`pyplot`: no display is needed, no global figure state is kept, and a figure is freed as soon as
it is saved.

One run (`plot_run`, after every `hil run`): `plot.png` in the run directory (`plot-NAME.png`
per joint when there are several), three panels on one time axis:
    1. link angle and its reference, motor angle and the goal sent to the actuator [rad]
       (contact experiment: the block's angle as a horizontal line)
    2. motor current [A] with the actuator's current limit (and the software guard's threshold
       when the guard is on)
    3. contact force [N] (experiments with an obstacle) or gear deflection link - motor [rad]
On every panel: the supervisor's events (safety stops, torque off) as vertical lines, torque-off
stretches shaded, the push shaded (impact), the first contact and the Overload bit (Hardware
Error Status 0x20) marked.

The comparisons follow the paper's figures (Kim et al., ICRA 2018, Sec. IV-B):
    Fig. 5 (a) desired and measured joint angle, (b) contact force, vs time, with the object
           contact and the overload protection marked;
    Fig. 6 measured joint angle after the 80 N push.
and the paper's line styles: PID blue dotted, GC+LQR+DOB with Kdist = 1 red dash-dot, with
Kdist = 0.5 green dashed; the other controllers (GC, GC+LQR) thinner and lighter.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from hil.experiments import Experiment
from hil.metrics import CONTACT_THRESHOLD_N, FIRST_PEAK_WINDOW_S, OVERLOAD_BIT
from hil.runlog import read_log
from hil.session import run_label

DPI = 110
_JOINT_COLUMN = re.compile(r"^link_angle_rad\[(.+)\]$")
# Events that are routine bookkeeping, not something that happened to the testbed.
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


# --- reading a run directory ------------------------------------------------------------------
@dataclass(frozen=True)
class RunData:
    """What a run directory holds (see hil.runlog): log columns, meta, summary and events."""

    out_dir: Path
    columns: dict[str, np.ndarray]
    meta: dict[str, Any]
    summary: dict[str, Any]
    events: tuple[dict[str, Any], ...]
    joint_names: tuple[str, ...]  # ("",) for a single-joint log (no column suffixes)

    @property
    def time_s(self) -> np.ndarray:
        return self.columns["time_s"]

    def signal(self, name: str, joint: str = "") -> np.ndarray:
        """A per-joint column: `name` for a single-joint log, `name[joint]` otherwise."""
        key = f"{name}[{joint}]" if joint else name
        try:
            return self.columns[key]
        except KeyError:
            raise KeyError(f"{self.out_dir / 'log.csv'} has no column {key!r}") from None

    @property
    def label(self) -> str:
        controller = str(self.meta.get("controller", "?"))
        return run_label(controller, float(self.meta.get("kdist", 0.0) or 0.0))

    @property
    def termination(self) -> str:
        return str(self.summary.get("termination", "unknown (no summary.json)"))


def load_run(out_dir: Path) -> RunData:
    """Read a run directory written by hil.runlog.RunLog; only log.csv is required."""
    out_dir = Path(out_dir)
    log_path = out_dir / "log.csv"
    if not log_path.is_file():
        raise FileNotFoundError(f"{out_dir} holds no log.csv: is it a run directory?")
    columns = read_log(log_path)
    if "time_s" not in columns:
        raise ValueError(f"{log_path} has no time_s column: not a hil run log")
    suffixed = tuple(m.group(1) for c in columns if (m := _JOINT_COLUMN.match(c)))
    joint_names = suffixed if suffixed else ("",)
    events: list[dict[str, Any]] = []
    events_path = out_dir / "events.jsonl"
    if events_path.is_file():
        events = [json.loads(line) for line in events_path.read_text().splitlines() if line]
    return RunData(
        out_dir=out_dir,
        columns=columns,
        meta=_read_json(out_dir / "meta.json"),
        summary=_read_json(out_dir / "summary.json"),
        events=tuple(events),
        joint_names=joint_names,
    )


def _read_json(path: Path) -> dict[str, Any]:
    if not path.is_file():
        return {}
    return json.loads(path.read_text())


def current_limits_a(run: RunData) -> list[float]:
    """The actuators' current caps in the run [A], as the loop recorded them in summary.json
    (what the devices reported at open); NaN where unknown."""
    limits = run.summary.get("current_limit_a") or []
    return [math.nan if v is None else float(v) for v in limits] or [math.nan]


def first_time(time_s: np.ndarray, mask: np.ndarray) -> float | None:
    index = np.flatnonzero(mask)
    return float(time_s[index[0]]) if index.size else None


def contact_time_s(run: RunData) -> float | None:
    """First tick the force sensor reads more than hil.metrics.CONTACT_THRESHOLD_N."""
    return first_time(run.time_s, run.columns["contact_force_n"] > CONTACT_THRESHOLD_N)


def overload_time_s(run: RunData, joint: str = "") -> float | None:
    """First tick the actuator reports its Overload bit (Hardware Error Status 0x20)."""
    bits = run.signal("hardware_error", joint).astype(int)
    return first_time(run.time_s, (bits & OVERLOAD_BIT) != 0)


def _torque_off_spans(time_s: np.ndarray, torque_on: np.ndarray) -> list[tuple[float, float]]:
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


def _save(figure: Figure, path: Path) -> Path:
    FigureCanvasAgg(figure)
    figure.savefig(path, dpi=DPI)
    return path


# --- one run ----------------------------------------------------------------------------------
def plot_run(out_dir: Path, experiment: Experiment) -> list[Path]:
    """Draw one run's PNG(s) into its directory; returns the files written."""
    run = load_run(out_dir)
    limits = current_limits_a(run)
    safety = run.meta.get("config", {}).get("safety", {})
    guard_fraction = safety.get("current_guard_fraction") if safety.get("current_guard") else None
    paths = []
    for index, joint in enumerate(run.joint_names):
        limit = limits[index] if index < len(limits) else limits[0]
        name = "plot.png" if len(run.joint_names) == 1 else f"plot-{joint}.png"
        figure = _run_figure(run, experiment, joint, limit, guard_fraction)
        paths.append(_save(figure, Path(out_dir) / name))
    return paths


def _run_figure(
    run: RunData,
    experiment: Experiment,
    joint: str,
    current_limit: float,
    guard_fraction: float | None,
) -> Figure:
    time = run.time_s
    figure = Figure(figsize=(10, 9), layout="constrained")
    angle_ax, current_ax, third_ax = figure.subplots(3, 1, sharex=True)
    joint_note = f", joint {joint}" if joint else ""
    setup = run.meta.get("setup", "")
    figure.suptitle(
        f"{experiment.name}: {run.label}{joint_note}"
        + (f" on the {setup}" if setup else "")
        + f"\n{experiment.title}\nended: {run.termination}",
        fontsize=10,
    )

    angle_ax.plot(time, run.signal("reference_rad", joint), "k-", lw=1.0, label="link reference")
    angle_ax.plot(time, run.signal("link_angle_rad", joint), color="tab:blue", label="link angle")
    angle_ax.plot(
        time, run.signal("motor_angle_rad", joint), color="tab:orange", label="motor angle"
    )
    angle_ax.plot(
        time, run.signal("goal_rad", joint), color="tab:green", ls="--", lw=1.0, label="goal"
    )
    if experiment.obstacle is not None:
        angle_ax.axhline(
            experiment.obstacle.contact_angle_rad, color="tab:brown", ls=":", lw=1.0, label="block"
        )
    angle_ax.set_ylabel("angle [rad]")

    current = run.signal("motor_current_a", joint)
    current_ax.plot(time, current, color="tab:purple", lw=1.0, label="motor current")
    for sign in (1.0, -1.0):
        current_ax.axhline(
            sign * current_limit,
            color="tab:red",
            ls="--",
            lw=1.0,
            label=f"current limit ±{current_limit:.2f} A" if sign > 0 else None,
        )
        if guard_fraction:
            current_ax.axhline(
                sign * guard_fraction * current_limit,
                color="tab:red",
                ls=":",
                lw=0.8,
                label=f"software guard {guard_fraction:.0%}" if sign > 0 else None,
            )
    trip = overload_time_s(run, joint)
    if trip is not None:
        index = max(int(np.searchsorted(time, trip)) - 1, 0)  # the current as it tripped
        current_ax.plot(
            trip, current[index], "X", color="tab:red", ms=9, label=f"Overload bit at {trip:.3f} s"
        )
    current_ax.set_ylabel("motor current [A]")

    contact = None
    if experiment.obstacle is not None:
        third_ax.plot(
            time, run.columns["contact_force_n"], color="tab:brown", label="contact force"
        )
        third_ax.set_ylabel("contact force [N]")
        contact = contact_time_s(run)
    else:
        deflection = run.signal("deflection_rad", joint)
        third_ax.plot(time, deflection, color="tab:cyan", label="deflection (link - motor)")
        third_ax.set_ylabel("deflection [rad]")
    third_ax.set_xlabel("time [s]")

    for ax in (angle_ax, current_ax, third_ax):
        _mark_world(ax, experiment, contact)
        _mark_torque_off(ax, time, run.signal("torque_enabled", joint))
        _mark_events(ax, run.events, float(time[-1]), label_them=ax is angle_ax)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize=8)
    return figure


def _mark_world(ax: Axes, experiment: Experiment, contact: float | None) -> None:
    for number, push in enumerate(experiment.pushes):
        ax.axvspan(
            push.start_s,
            push.start_s + push.duration_s,
            color="tab:red",
            alpha=0.25,
            label=f"push {abs(push.force_n):g} N" if number == 0 else None,
        )
    if contact is not None:
        ax.axvline(contact, color="tab:brown", ls="-.", lw=1.0, label=f"contact at {contact:.3f} s")


def _mark_torque_off(ax: Axes, time: np.ndarray, torque_on: np.ndarray) -> None:
    for number, (start, end) in enumerate(_torque_off_spans(time, torque_on)):
        ax.axvspan(start, end, color="0.5", alpha=0.15, label="torque off" if number == 0 else None)


def _mark_events(
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


# --- the comparisons (Figs. 5 and 6) ----------------------------------------------------------
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


def comparison_style(controller: str, kdist: float) -> LineStyle:
    """The paper's styles (Figs. 5, 6) for PID and GC+LQR+DOB; the others lighter."""
    if controller == "pid":
        return LineStyle("tab:blue", ":", 2.0, 1.0, True)
    if controller == "gc+lqr+dob":
        if math.isclose(kdist, 1.0):
            return LineStyle("tab:red", "-.", 1.8, 1.0, True)
        if math.isclose(kdist, 0.5):
            return LineStyle("tab:green", "--", 1.8, 1.0, True)
        return LineStyle("tab:purple", "--", 1.5, 1.0, True)
    if controller == "gc+lqr":
        return LineStyle("tab:orange", "-", 1.0, 0.5, False)
    if controller.startswith("gc+lqr+dob/"):  # the other reading of (25)
        return LineStyle("tab:brown", "-", 1.2, 0.8, False)
    return LineStyle("0.45", "-", 1.0, 0.5, False)


@dataclass(frozen=True)
class ComparisonRun:
    """One run in a comparison figure: its label, controller and Kdist, and its data."""

    label: str
    controller: str
    kdist: float
    run: RunData

    @property
    def style(self) -> LineStyle:
        return comparison_style(self.controller, self.kdist)


def _comparison_title(experiment: Experiment, setup: str) -> str:
    where = f" on the {setup}" if setup else ""
    return f"{experiment.title}\nKim et al., ICRA 2018, reproduced{where}"


def _in_drawing_order(runs: Sequence[ComparisonRun]) -> list[ComparisonRun]:
    return sorted(runs, key=lambda r: r.style.highlighted)


def plot_contact_comparison(
    runs: Sequence[ComparisonRun], experiment: Experiment, path: Path, setup: str = ""
) -> Path:
    """Fig. 5: (a) desired and measured link angle, (b) contact force, all controllers."""
    if not runs:
        raise ValueError("plot_contact_comparison needs at least one run")
    figure = Figure(figsize=(10, 8), layout="constrained")
    angle_ax, force_ax = figure.subplots(2, 1, sharex=True)
    figure.suptitle(_comparison_title(experiment, setup), fontsize=10)
    first = runs[0].run
    angle_ax.plot(
        first.time_s,
        first.signal("reference_rad", first.joint_names[0]),
        "k-",
        lw=1.2,
        label="desired",
        zorder=4,
    )
    if experiment.obstacle is not None:
        angle_ax.axhline(
            experiment.obstacle.contact_angle_rad, color="tab:brown", ls=":", lw=1.0, label="block"
        )
    contacts: list[float] = []
    for entry in _in_drawing_order(runs):
        run, style = entry.run, entry.style
        joint = run.joint_names[0]
        angle = run.signal("link_angle_rad", joint)
        force = run.columns["contact_force_n"]
        angle_ax.plot(run.time_s, angle, label=entry.label, **style.kwargs())
        force_ax.plot(run.time_s, force, label=entry.label, **style.kwargs())
        marker_alpha = 1.0 if style.highlighted else 0.5
        contact = contact_time_s(run)
        if contact is not None:
            contacts.append(contact)
            i = int(np.searchsorted(run.time_s, contact))
            angle_ax.plot(contact, angle[i], "o", color=style.color, alpha=marker_alpha, ms=5)
            force_ax.plot(contact, force[i], "o", color=style.color, alpha=marker_alpha, ms=5)
        trip = overload_time_s(run, joint)
        if trip is not None:
            # the last sample before the trip: where the run was when the protection acted
            i = max(int(np.searchsorted(run.time_s, trip)) - 1, 0)
            for ax, values in ((angle_ax, angle), (force_ax, force)):
                ax.plot(trip, values[i], "X", color=style.color, alpha=marker_alpha, ms=9)
            if style.highlighted:
                for ax in (angle_ax, force_ax):
                    ax.axvline(trip, color=style.color, ls=":", lw=0.8)
                force_ax.annotate(
                    f"overload protection\n({entry.label}, {trip:.2f} s)",
                    xy=(trip, force[i]),
                    xytext=(8, 8),
                    textcoords="offset points",
                    fontsize=8,
                    color=style.color,
                )
    if contacts:
        first_contact = min(contacts)
        for ax in (angle_ax, force_ax):
            ax.axvline(first_contact, color="tab:brown", ls="-.", lw=0.8)
        angle_ax.annotate(
            f"object contact ({first_contact:.2f} s)",
            xy=(first_contact, 1.0),
            xycoords=("data", "axes fraction"),
            xytext=(4, -12),
            textcoords="offset points",
            fontsize=8,
            color="tab:brown",
        )
    angle_ax.set_ylabel("(a) joint angle [rad]")
    force_ax.set_ylabel("(b) contact force [N]")
    force_ax.set_xlabel("time [s]")
    for ax in (angle_ax, force_ax):
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize=8, title="o contact, X overload", title_fontsize=7)
    return _save(figure, path)


def plot_impact_comparison(
    runs: Sequence[ComparisonRun], experiment: Experiment, path: Path, setup: str = ""
) -> Path:
    """Fig. 6: link angle vs time after the push, the first peak of each run marked."""
    if not runs:
        raise ValueError("plot_impact_comparison needs at least one run")
    if not experiment.pushes:
        raise ValueError(f"experiment {experiment.name!r} has no push to align the runs on")
    push = experiment.pushes[0]
    figure = Figure(figsize=(10, 5.5), layout="constrained")
    ax = figure.subplots()
    figure.suptitle(_comparison_title(experiment, setup), fontsize=10)
    ax.axvspan(
        0.0,
        push.duration_s,
        color="tab:red",
        alpha=0.2,
        label=f"push {abs(push.force_n):g} N, {push.duration_s * 1e3:g} ms",
    )
    lead_s = 0.25
    for entry in _in_drawing_order(runs):
        run, style = entry.run, entry.style
        since = run.time_s - push.start_s
        angle = run.signal("link_angle_rad", run.joint_names[0])
        shown = since >= -lead_s
        ax.plot(since[shown], angle[shown], label=entry.label, **style.kwargs())
        before = np.flatnonzero(since < 0.0)
        window = np.flatnonzero((since >= 0.0) & (since < FIRST_PEAK_WINDOW_S))
        if before.size and window.size:
            peak = window[np.nanargmax(np.abs(angle[window] - angle[before[-1]]))]
            ax.plot(
                since[peak],
                angle[peak],
                "v",
                color=style.color,
                ms=6,
                alpha=1.0 if style.highlighted else 0.5,
            )
    ax.set_xlabel(f"time since the push [s] (push at t = {push.start_s:g} s)")
    ax.set_ylabel("joint angle [rad]")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8, title="v first peak", title_fontsize=7)
    return _save(figure, path)
