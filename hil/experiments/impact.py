"""Impact (Kim et al., ICRA 2018, Sec. IV-B, Fig. 6): an 80 N push on the load while the link holds.

The link holds horizontal; at t = 1 s the load gets an 80 N push (the paper's figure) downwards
for 20 ms (a hand or hammer strike; the duration is not published).

Metrics (from the run's log, over all joints: the largest figure of any joint):
    first_peak_rad              largest |link angle - link angle just before the push| within
                                FIRST_PEAK_WINDOW_S after the push starts
    settling_time_s             from the push until the link stays within
                                max(SETTLING_FRACTION x first peak, SETTLING_FLOOR_RAD) of its
                                final value (the mean of the last FINAL_WINDOW_S)
    oscillations                sign changes of (link - final) above the settling band after
                                the push: a count of half-periods of ringing
    quasi_static_error_rad      |link - reference| QUASI_STATIC_AFTER_PUSH_S after the push (where
                                the paper's 5 s run ends): what the paper calls the steady-state
                                error. It is not an equilibrium: the servo's velocity-loop
                                integral (Ti = 15 s on the emulated H54) still winds it out
    equilibrium_error_rad       |e_eq| of the slow mode e(t) = e_eq + A exp(-t / tau) fitted from
                                EQUILIBRIUM_FIT_AFTER_PUSH_S after the push to the end
                                (hil/experiments/steady_state.py); None when the run is too short
                                to tell (`unmeasured` says why: a 5 s run always is)
    slow_time_constant_s        the fitted tau (None as above)

A metric whose window the run did not cover (the first peak's 0.5 s after the push, the final
value after it, the error 3.75 s after the push) is None, and `unmeasured` ({metric: why})
says why: a `--duration 1` run ends 25 ms after the push and measures none of them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hil.experiments.base import Push, TestbedExperiment, World
from hil.experiments.steady_state import SlowModeFitError, fit_slow_mode, quasi_static_error
from hil.output.plots import ComparisonRun, comparison_title, in_drawing_order, save_figure
from hil.output.records import UNMEASURED, RunEntry
from hil.output.report import (
    Column,
    Missing,
    Relation,
    check,
    find,
    half_periods,
    metric,
    number,
)
from hil.output.rundir import RunData
from hil.vocabulary import ControllerChoice, ControllerKind

IMPACT_METRICS = (
    "first_peak_rad",
    "settling_time_s",
    "oscillations",
    "quasi_static_error_rad",
    "equilibrium_error_rad",
    "slow_time_constant_s",
)
FIRST_PEAK_WINDOW_S = 0.5
SETTLING_FRACTION = 0.1
SETTLING_FLOOR_RAD = 0.5e-3
FINAL_WINDOW_S = 0.5
QUASI_STATIC_AFTER_PUSH_S = 3.75  # 4 s after the push the paper's 5 s run ends; a 0.1 s window
EQUILIBRIUM_FIT_AFTER_PUSH_S = 3.0  # after the push's fast transients
# "zero" for an equilibrium error: a tenth of the smallest quasi-static error we report (1 mrad)
EQUILIBRIUM_ZERO_RAD = 1e-3

# --- the paper's figures (Kim et al., ICRA 2018, Sec. IV-B, Fig. 6) -----------------------------
PAPER_FIRST_PEAK_RAD = {"pid": 0.038, "dob_kdist_1": 0.079}  # first oscillation
PAPER_STEADY_STATE_ERROR_RAD = {1.0: 0.0021, 0.5: 0.0012}  # by Kdist
# "the vibration is then quickly reduced in the proposed algorithm" presumes that PID keeps
# vibrating: at least one full period (two half-periods) of ringing outside the settling band.
PID_RINGING_HALF_PERIODS = 2


def joint_impact_metrics(
    time: np.ndarray, link: np.ndarray, reference: np.ndarray, push_start_s: float
) -> dict[str, Any]:
    """The metrics of one joint's link angle around a push at `push_start_s` (loop time)."""
    period = float(np.median(np.diff(time))) if time.size > 1 else 0.005
    before = np.flatnonzero(time < push_start_s)
    after = time >= push_start_s
    if not before.size or not after.any():
        raise ValueError("the log does not cover the push")
    metrics: dict[str, Any] = dict.fromkeys(IMPACT_METRICS)
    unmeasured: dict[str, str] = {}
    # a window counts as covered when the log reaches its last tick
    covered_s = float(time[-1]) + period - push_start_s  # the log after the push starts
    peak_s, settled_s = FIRST_PEAK_WINDOW_S, FIRST_PEAK_WINDOW_S + FINAL_WINDOW_S
    baseline = link[before[-1]]
    window = after & (time < push_start_s + FIRST_PEAK_WINDOW_S)
    valid = window & np.isfinite(link)
    if covered_s < peak_s - period / 2:
        unmeasured["first_peak_rad"] = (
            f"the run ends {covered_s:.3f} s after the push; the first peak is looked for over "
            f"{peak_s:g} s after it"
        )
    elif not np.isfinite(baseline) or not valid.any():
        unmeasured["first_peak_rad"] = "no valid link reading at the push or in its first window"
    else:
        metrics["first_peak_rad"] = float(np.max(np.abs(link[valid] - baseline)))
    final_count = max(1, int(round(FINAL_WINDOW_S / period)))
    final_values = link[-final_count:]
    for key in ("settling_time_s", "oscillations"):
        if covered_s < settled_s - period / 2:
            unmeasured[key] = (
                f"the run ends {covered_s:.3f} s after the push; settling is judged against the "
                f"final value, the last {FINAL_WINDOW_S:g} s of a run at least {settled_s:g} s "
                "after the push"
            )
        elif metrics["first_peak_rad"] is None or not np.isfinite(final_values).any():
            unmeasured[key] = "no first peak or no valid final value to judge it against"
    if not {"settling_time_s", "oscillations"} & unmeasured.keys():
        final = float(np.nanmean(final_values))
        band = max(SETTLING_FRACTION * metrics["first_peak_rad"], SETTLING_FLOOR_RAD)
        deviation = link[after] - final
        outside = np.flatnonzero(np.abs(deviation) > band)
        settling = float(time[after][outside[-1]] + period - push_start_s) if outside.size else 0.0
        significant = deviation[np.abs(deviation) > band]
        metrics["settling_time_s"] = settling
        metrics["oscillations"] = int(np.count_nonzero(np.diff(np.sign(significant)) != 0))
    if time[-1] >= push_start_s + QUASI_STATIC_AFTER_PUSH_S:
        error = quasi_static_error(time, link, reference, push_start_s, QUASI_STATIC_AFTER_PUSH_S)
        metrics["quasi_static_error_rad"] = abs(error.error_rad)
    else:
        unmeasured["quasi_static_error_rad"] = (
            f"the run ends {covered_s:.3f} s after the push, before the "
            f"{QUASI_STATIC_AFTER_PUSH_S:g} s at which the error is read"
        )
    try:
        fit = fit_slow_mode(time, link, reference, push_start_s + EQUILIBRIUM_FIT_AFTER_PUSH_S)
    except SlowModeFitError as exc:
        unmeasured["equilibrium_error_rad"] = unmeasured["slow_time_constant_s"] = str(exc)
    else:
        metrics["equilibrium_error_rad"] = abs(fit.equilibrium_error_rad)
        metrics["slow_time_constant_s"] = fit.time_constant_s
    if unmeasured:
        metrics[UNMEASURED] = unmeasured
    return metrics


def _worst(values: list[Any]) -> Any:
    """The largest figure of any joint (None where a joint has none; notes: the first)."""
    numbers = [v for v in values if isinstance(v, int | float)]
    if numbers:
        return max(numbers)
    return next((v for v in values if v is not None), None)


@dataclass(frozen=True)
class ImpactExperiment(TestbedExperiment):
    def metrics(self, run: RunData) -> dict[str, Any]:
        if not self.world.pushes:
            return {}
        push_start = self.world.pushes[0].start_s + run.experiment_start_s
        per_joint = [
            joint_impact_metrics(
                run.time_s,
                run.signal("link_angle_rad", joint),
                run.signal("reference_rad", joint),
                push_start,
            )
            for joint in run.joint_names
        ]
        keys = dict.fromkeys(key for metrics in per_joint for key in metrics if key != UNMEASURED)
        merged = {key: _worst([m.get(key) for m in per_joint]) for key in keys}
        unmeasured: dict[str, str] = {}
        for joint, metrics in zip(run.joint_names, per_joint, strict=True):
            for key, why in metrics.get(UNMEASURED, {}).items():
                unmeasured.setdefault(key, f"{joint}: {why}" if joint else why)
                merged[key] = None  # not the worst of the joints that could be measured
        return {**merged, UNMEASURED: unmeasured} if unmeasured else merged

    @property
    def figure_name(self) -> str:
        return "fig6_impact.png"

    @property
    def report_columns(self) -> tuple[Column, ...]:
        return (
            Column("first_peak_rad", "first peak [rad]", number(".4f")),
            Column("settling_time_s", "settling [s]", number(".2f")),
            Column("oscillations", "oscillations", number("d")),
            Column("quasi_static_error_rad", "error 3.75 s after push [rad]", number(".4f")),
            Column("equilibrium_error_rad", "equilibrium error [rad]", number(".4f")),
            Column("slow_time_constant_s", "slow mode [s]", number(".1f")),
        )

    def comparison_figure(
        self, runs: Sequence[ComparisonRun], path: Path, setup: str
    ) -> Path | None:
        return plot_impact_comparison(runs, self, path, setup) if runs else None

    def relations(self, entries: Sequence[RunEntry]) -> list[Relation]:
        return impact_relations(self.name, entries)


IMPACT = ImpactExperiment(
    name="impact",
    title="Impact (Fig. 6): an 80 N push on the load while holding",
    duration_s=5.0,
    initial_angle_rad=0.0,
    world=World(pushes=(Push(start_s=1.0, duration_s=0.02, force_n=-80.0),)),
)


# --- the paper's claims -----------------------------------------------------------------------
def impact_relations(exp: str, entries: Sequence[RunEntry]) -> list[Relation]:
    """Every claim of Sec. IV-B about the impact experiment."""
    dob = ControllerKind.GC_LQR_DOB
    pid = find(entries, exp, ControllerKind.PID)
    high = find(entries, exp, dob, 1.0)
    middle = find(entries, exp, dob, 0.5)
    high_label = ControllerChoice(dob, 1.0).label
    middle_label = ControllerChoice(dob, 0.5).label
    relations = []

    def first_peak_vs_pid() -> tuple[bool, str]:
        ours_high = metric(high, "first_peak_rad", high_label)
        ours_pid = metric(pid, "first_peak_rad", "pid")
        return ours_high > ours_pid, f"{ours_high:.4f} vs {ours_pid:.4f} rad"

    relations.append(
        check(
            exp,
            f"first peak larger with {high_label} than with pid",
            f"{PAPER_FIRST_PEAK_RAD['dob_kdist_1']:g} vs {PAPER_FIRST_PEAK_RAD['pid']:g} rad",
            first_peak_vs_pid,
        )
    )

    def more_compliant() -> tuple[bool, str]:
        ours_high = metric(high, "first_peak_rad", high_label)
        ours_middle = metric(middle, "first_peak_rad", middle_label)
        return ours_high > ours_middle, f"first peak {ours_high:.4f} vs {ours_middle:.4f} rad"

    relations.append(
        check(
            exp,
            f"{high_label} more compliant than {middle_label} (larger first peak)",
            "Kdist 1 more compliant (Fig. 6)",
            more_compliant,
        )
    )

    def pid_rings() -> tuple[bool, str]:
        oscillations = metric(pid, "oscillations", "pid")
        return oscillations >= PID_RINGING_HALF_PERIODS, half_periods(oscillations)

    relations.append(
        check(
            exp,
            "pid rings after the push",
            "PID vibration persists (Fig. 6)",
            pid_rings,
            f"holds for >= {PID_RINGING_HALF_PERIODS} half-periods outside the settling band "
            "(impact metric `oscillations`)",
        )
    )

    return [*relations, *_settling_relations(exp, entries)]


def _settling_relations(exp: str, entries: Sequence[RunEntry]) -> list[Relation]:
    """After the push: who settles faster than pid, and the Kdist order of the offset."""
    dob = ControllerKind.GC_LQR_DOB
    pid = find(entries, exp, ControllerKind.PID)
    high = find(entries, exp, dob, 1.0)
    middle = find(entries, exp, dob, 0.5)
    high_label = ControllerChoice(dob, 1.0).label
    middle_label = ControllerChoice(dob, 0.5).label
    relations = []
    faster = [(high, high_label), (middle, middle_label)]
    gc_lqr = find(entries, exp, ControllerKind.GC_LQR)
    if gc_lqr is not None:
        faster.append((gc_lqr, "gc+lqr"))
    for entry, label in faster:

        def settles_faster(entry: RunEntry | None = entry, label: str = label) -> tuple[bool, str]:
            settling = metric(entry, "settling_time_s", label)
            oscillations = metric(entry, "oscillations", label)
            settling_pid = metric(pid, "settling_time_s", "pid")
            oscillations_pid = metric(pid, "oscillations", "pid")
            return settling < settling_pid, (
                f"settles in {settling:.2f} s ({half_periods(oscillations)}) vs "
                f"{settling_pid:.2f} s ({half_periods(oscillations_pid)})"
            )

        relations.append(
            check(
                exp,
                f"the motion after the push dies out faster with {label} than with pid",
                "quickly reduced with LQR/DOB",
                settles_faster,
                "holds when the settling time (impact metric) is shorter than pid's",
            )
        )

    def quasi_static() -> tuple[bool, str]:
        ours_high = metric(high, "quasi_static_error_rad", high_label)
        ours_middle = metric(middle, "quasi_static_error_rad", middle_label)
        if ours_high is None or ours_middle is None:
            raise Missing(f"a run shorter than {QUASI_STATIC_AFTER_PUSH_S} s after the push")
        return ours_high > ours_middle, f"{ours_high:.4f} vs {ours_middle:.4f} rad"

    relations.append(
        check(
            exp,
            f"the error {QUASI_STATIC_AFTER_PUSH_S:g} s after the push (the paper's "
            f"'steady-state error') larger with {high_label} than with {middle_label}",
            f"{PAPER_STEADY_STATE_ERROR_RAD[1.0]:g} vs {PAPER_STEADY_STATE_ERROR_RAD[0.5]:g} rad",
            quasi_static,
            "a quasi-static error, not an equilibrium: see the long impact runs",
        )
    )
    return relations


# --- Fig. 6 -----------------------------------------------------------------------------------
def plot_impact_comparison(
    runs: Sequence[ComparisonRun], experiment: ImpactExperiment, path: Path, setup: str = ""
) -> Path:
    """Fig. 6: link angle vs time after the push, the first peak of each run marked."""
    if not runs:
        raise ValueError("plot_impact_comparison needs at least one run")
    if not experiment.world.pushes:
        raise ValueError(f"experiment {experiment.name!r} has no push to align the runs on")
    push = experiment.world.pushes[0]
    from matplotlib.figure import Figure

    figure = Figure(figsize=(10, 5.5), layout="constrained")
    ax = figure.subplots()
    figure.suptitle(comparison_title(experiment.title, setup), fontsize=10)
    ax.axvspan(
        0.0,
        push.duration_s,
        color="tab:red",
        alpha=0.2,
        label=f"push {abs(push.force_n):g} N, {push.duration_s * 1e3:g} ms",
    )
    lead_s = 0.25
    for entry in in_drawing_order(runs):
        run, style = entry.run, entry.style
        since = run.time_s - (push.start_s + run.experiment_start_s)
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
    return save_figure(figure, path)


@dataclass(frozen=True)
class LongImpactExperiment(ImpactExperiment):
    """The impact, held a minute: long enough to fit the slow mode and see the equilibrium."""

    @property
    def figure_name(self) -> str:
        return "fig6_impact_long.png"

    def relations(self, entries: Sequence[RunEntry]) -> list[Relation]:
        return equilibrium_relations(self.name, entries)


IMPACT_LONG = LongImpactExperiment(
    name="impact-long",
    title="Impact (Fig. 6) held for a minute: the error after the push at its equilibrium",
    duration_s=61.0,
    initial_angle_rad=0.0,
    world=IMPACT.world,
)


def equilibrium_relations(exp: str, entries: Sequence[RunEntry]) -> list[Relation]:
    """The paper's steady-state relation read at the equilibrium of the slow mode."""
    dob = ControllerKind.GC_LQR_DOB
    high, middle = find(entries, exp, dob, 1.0), find(entries, exp, dob, 0.5)
    high_label = ControllerChoice(dob, 1.0).label
    middle_label = ControllerChoice(dob, 0.5).label

    def equilibrium() -> tuple[bool, str]:
        ours = []
        for entry, label in ((high, high_label), (middle, middle_label)):
            value = metric(entry, "equilibrium_error_rad", label)
            if value is None:
                note = (entry.result.metrics.get(UNMEASURED) or {}).get("equilibrium_error_rad")
                raise Missing(f"no equilibrium for {label}: {note}")
            tau = metric(entry, "slow_time_constant_s", label)
            ours.append((value, tau))
        (e_high, tau_high), (e_middle, tau_middle) = ours
        text = (
            f"{e_high:.4f} vs {e_middle:.4f} rad (slow modes {tau_high:.1f} s and "
            f"{tau_middle:.1f} s)"
        )
        return e_high > e_middle and e_high > EQUILIBRIUM_ZERO_RAD, text

    return [
        check(
            exp,
            f"at the equilibrium, the error after the push is larger with {high_label} than "
            f"with {middle_label}",
            f"{PAPER_STEADY_STATE_ERROR_RAD[1.0]:g} vs {PAPER_STEADY_STATE_ERROR_RAD[0.5]:g} rad",
            equilibrium,
            "the servo's velocity-loop integral winds the error out with its integral time; an "
            f"equilibrium below {EQUILIBRIUM_ZERO_RAD:g} rad counts as none",
        )
    ]
