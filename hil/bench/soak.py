"""`hil bench soak`: many lock-step runs with a random fault each, every reaction checked.

Each run is the loop of `hil run` on the in-process joint bus (the emulator's devices, firmware,
plant and fault schedule, without the pseudo-terminals), with one fault of one kind at a random
time; the kinds take turns, so every kind is injected about as often. After every run the soak
checks what docs/safety.md promises:
    reaction   the documented cause and reaction, within the documented number of ticks from
               the first tick that sees the fault (or, for a single lost reply, no safe state
               and a notice)
    log        one row per tick, the tick column without a gap, summary and events written
    exit       the torque state the configuration asks for (`on_exit`), on the device itself;
               where the device could not hear it (a silent actuator) the run must say so
The figures (faults per kind, reactions within bound, worst ticks, rows lost, exit states) are
printed; nothing here asserts a timing.
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hil.config import Config
from hil.experiments import CONTACT, Experiment
from hil.loop import LockstepClock, RunRequest, run_experiment
from hil.output import load_run
from hil.vocabulary import ControllerChoice, ControllerKind
from hil.wiring.in_process import in_process_bus
from sim_backend.scenario import FaultEvent

DEFAULT_SOAK_TICKS = 100_000
# The link-noise watch finds random noise in a random time: for the emulator's noisy_encoder
# (50 counts rms) at the default settings, 15 ticks at the median, one fault in thirty past
# one window (20 ticks), about 4 in 10**7 past three (docs/safety.md, "Noise vs. motion").
# Its bound is three windows; one window would fail a soak at some seeds, not the watch.
NOISE_DETECTION_WINDOWS = 3


@dataclass(frozen=True)
class SoakKind:
    """One kind of fault and what must follow it (docs/safety.md, "Faults and reactions")."""

    name: str
    cause: str | None  # None: tolerated, with `notice`
    action: str | None
    bound_ticks: Callable[[Config], int]
    window_s: tuple[float, float]  # when the fault may start (experiment time)
    experiment: Experiment = CONTACT
    controller: ControllerKind = ControllerKind.GC_LQR_DOB
    duration_s: float | None = None  # of the fault; None: one reply / to the end
    notice: str | None = None
    run_after_s: float = 0.4  # how long the run goes on after the fault starts
    # the bound counts from when the motor has turned half the deflection bound since the
    # fault (a frozen reading is a fault only while the joint moves: docs/safety.md)
    after_motion: bool = False


def _kinds() -> tuple[SoakKind, ...]:
    bus = lambda c: c.safety.bus_error_ticks  # noqa: E731 - a table of small rules
    link = lambda c: c.safety.link_stale_ticks  # noqa: E731
    return (
        SoakKind("dropped_reply", None, None, lambda c: 1, (0.5, 3.0), notice="bus_glitch"),
        SoakKind("corrupt_crc", None, None, lambda c: 1, (0.5, 3.0), notice="bus_glitch"),
        SoakKind("dropped_reply", "bus_error", "torque_off", bus, (0.5, 3.0), duration_s=0.05),
        SoakKind("corrupt_crc", "bus_error", "torque_off", bus, (0.5, 3.0), duration_s=0.05),
        SoakKind("silent_id", "bus_error", "torque_off", bus, (0.5, 3.0), run_after_s=0.15),
        SoakKind("dead_encoder", "link_stale", "hold", link, (0.5, 3.0)),
        # frozen while the motor moves (the contact ramp, 1-3 s)
        SoakKind("stale_encoder", "link_stale", "hold", link, (1.3, 2.0), after_motion=True),
        SoakKind(
            "noisy_encoder",
            "link_noisy",
            "hold",
            lambda c: NOISE_DETECTION_WINDOWS * c.safety.link_noise_window_ticks,
            (0.5, 3.0),
        ),
        SoakKind(
            "overrun",
            "overrun",
            "hold",
            lambda c: c.safety.overrun_limit + 1,
            (0.5, 3.0),
            duration_s=0.2,
        ),
        # pid into the block, the software guard off: the actuator's own overload protection
        SoakKind(
            "overload",
            "hardware_error",
            "torque_off",
            lambda c: 1,
            (0.0, 0.0),
            controller=ControllerKind.PID,
            run_after_s=4.6,
        ),
    )


KINDS = _kinds()


@dataclass
class KindFigures:
    injected: int = 0
    within_bound: int = 0
    worst_ticks: int = 0
    rows_lost: int = 0
    exits: dict[str, int] = field(default_factory=dict)
    failures: list[str] = field(default_factory=list)


def _label(kind: SoakKind) -> str:
    if kind.duration_s is not None:
        return f"{kind.name}+{kind.duration_s:g}"
    return kind.name


def _run_one(
    config: Config, kind: SoakKind, start_s: float, out_dir: Path, seed: int
) -> tuple[int, dict[str, Any]]:
    """One run with one fault; returns (ticks, the checks' outcome)."""
    faults: tuple[FaultEvent, ...] = ()
    overruns: tuple[tuple[float, float], ...] = ()
    if kind.name == "overrun":
        overruns = ((start_s, kind.duration_s or 0.02),)
    elif kind.name != "overload":
        faults = (FaultEvent(kind.name, start_s, kind.duration_s),)
    run_config = config
    if kind.name == "overload":
        run_config = config.changed("safety", current_guard=False)
    bus = in_process_bus(run_config, kind.experiment, faults, seed=seed)
    request = RunRequest(
        kind.experiment,
        ControllerChoice(kind.controller, run_config.controller.kdist),
        out_dir,
        duration_s=start_s + kind.run_after_s,
        overruns=overruns,
    )
    result = run_experiment(run_config, request, bus, LockstepClock(config.loop.period_s), {})
    run = load_run(out_dir)
    assert bus.testbed is not None
    torque_on = bool(bus.testbed.robot.devices[0].torque_enabled)
    return result.ticks, _check(run_config, kind, start_s, run, torque_on)


def _fault_tick(kind: SoakKind, start_s: float, run: Any, period_s: float) -> int:
    if kind.name == "overload":  # when the device reported it
        flags = run.columns["actuator_fault"]
        hits = np.flatnonzero(flags != 0)
        return int(run.columns["tick"][hits[0]]) if hits.size else -1
    return math.ceil(start_s / period_s - 1e-9)  # the first tick at or after the start


def _ticks_until_moved(run: Any, fault_tick: int, angle_rad: float) -> int:
    """Ticks from the fault until the motor had turned `angle_rad` from where it was then (a
    large number when it never did)."""
    ticks = run.columns["tick"].astype(int)
    motor = run.columns["motor_angle_rad"]
    at = np.flatnonzero(ticks >= fault_tick)
    if not at.size:
        return 10**9
    moved = np.flatnonzero(np.abs(motor[at] - motor[at[0]]) > angle_rad)
    return int(moved[0]) if moved.size else 10**9


def _check(
    config: Config, kind: SoakKind, start_s: float, run: Any, torque_on: bool
) -> dict[str, Any]:
    summary = run.summary
    ticks = run.columns["tick"].astype(int)
    rows_lost = int(summary["ticks"] - len(ticks))
    gapless = bool(np.all(np.diff(ticks) == 1)) and (ticks.size == 0 or ticks[0] == 0)
    fault_tick = _fault_tick(kind, start_s, run, config.loop.period_s)
    events = summary["safety_events"]
    outcome: dict[str, Any] = {"rows_lost": rows_lost if gapless else max(rows_lost, 1)}
    if kind.cause is None:
        notices = [n for n in summary["safety_notices"] if n["kind"] == kind.notice]
        outcome["reaction_ticks"] = 1 if notices else None
        outcome["ok"] = not events and bool(notices)
    else:
        first = events[0] if events else None
        right = first is not None and (first["cause"], first["action"]) == (
            kind.cause,
            kind.action,
        )
        reaction = first["tick"] - fault_tick + 1 if right and fault_tick >= 0 else None
        outcome["reaction_ticks"] = reaction
        bound = kind.bound_ticks(config)
        if kind.after_motion:
            bound += _ticks_until_moved(run, fault_tick, config.safety.max_deflection_rad / 2)
        outcome["ok"] = reaction is not None and 1 <= reaction <= bound
    exit_note = summary["exit"][0] if summary["exit"] else "?"
    wanted_off = config.safety.on_exit == "torque_off"
    said_off = exit_note.startswith("torque off") and "FAILED" not in exit_note  # (N tries)
    honest = said_off == (not torque_on) if wanted_off else True
    outcome["exit"] = exit_note if honest else f"DISHONEST: {exit_note}, torque on={torque_on}"
    outcome["ok"] = outcome["ok"] and honest and outcome["rows_lost"] == 0
    return outcome


def run_soak(
    config: Config,
    ticks: int = DEFAULT_SOAK_TICKS,
    *,
    seed: int = 0,
    say: Callable[[str], None] = lambda _text: None,
) -> dict[str, Any]:
    """Runs with one random fault each, the kinds in turn, until `ticks` ticks have run."""
    rng = np.random.default_rng(seed)
    figures = {_label(kind): KindFigures() for kind in KINDS}
    total = runs = 0
    with tempfile.TemporaryDirectory(prefix="hil-soak-") as tmp:
        while total < ticks:
            kind = KINDS[runs % len(KINDS)]
            low, high = kind.window_s
            start_s = float(np.round(rng.uniform(low, high), 3)) if high > low else low
            run_ticks, outcome = _run_one(
                config, kind, start_s, Path(tmp) / f"run{runs}", seed=int(rng.integers(1 << 31))
            )
            _account(figures[_label(kind)], kind, start_s, outcome)
            total += run_ticks
            runs += 1
            if runs % len(KINDS) == 0:
                say(f"soak: {runs} runs, {total} ticks")
    return {
        "bench": "soak",
        "ticks": total,
        "runs": runs,
        "seed": seed,
        "kinds": {name: vars(f) for name, f in figures.items()},
        "all_within_bound": all(f.injected == f.within_bound for f in figures.values()),
        "rows_lost": sum(f.rows_lost for f in figures.values()),
    }


def _account(fig: KindFigures, kind: SoakKind, start_s: float, outcome: dict[str, Any]) -> None:
    fig.injected += 1
    fig.within_bound += int(outcome["ok"])
    fig.worst_ticks = max(fig.worst_ticks, outcome["reaction_ticks"] or 0)
    fig.rows_lost += outcome["rows_lost"]
    fig.exits[outcome["exit"]] = fig.exits.get(outcome["exit"], 0) + 1
    if not outcome["ok"] and len(fig.failures) < 5:
        fig.failures.append(f"{kind.name}@{start_s:g}: {outcome}")


def soak_report_text(report: dict[str, Any]) -> str:
    lines = [
        f"hil bench soak: {report['runs']} lock-step runs, {report['ticks']} ticks, seed "
        f"{report['seed']} (in-process bus, one random fault per run)",
        "",
        f"  {'fault':<22} {'injected':>8} {'within bound':>12} {'worst ticks':>11} "
        f"{'rows lost':>9}  exit states",
    ]
    for name, fig in report["kinds"].items():
        exits = ", ".join(f"{k}: {v}" for k, v in sorted(fig["exits"].items()))
        lines.append(
            f"  {name:<22} {fig['injected']:>8} {fig['within_bound']:>12} "
            f"{fig['worst_ticks']:>11} {fig['rows_lost']:>9}  {exits}"
        )
        lines += [f"    FAILED: {failure}" for failure in fig["failures"]]
    verdict = "every reaction within its bound" if report["all_within_bound"] else "FAILURES"
    lines += ["", f"  {verdict}; rows lost in all: {report['rows_lost']}"]
    return "\n".join(lines)
