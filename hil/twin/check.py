"""How far a twin's replays are from the record: `hil twin --check TWIN RUN_DIR...`.

Each run is replayed twice on the twin and twice on the default emulator (the run's own recorded
configuration, as `hil run --emulate` would have emulated it), all in process:
    open loop     the recorded goals and torque states (hil/twin/replay.py `replay_goals`)
    closed loop   the recorded experiment with the recorded controller (`replay_closed_loop`;
                  not for an open-loop experiment such as `identify`, whose goals are the
                  experiment)
The twin of a run is the run's configuration with the twin's [emulator] section (its
controller, safety and model as recorded). Per run, joint and signal (motor angle, link angle,
deflection in mrad, current in A; the contact force in N for a run with a block): the mean
absolute error and the rms of replayed - recorded over the ticks both have, written to
report.md and check.json with a figure per run (recorded, twin, default; closed loop where
there is one).
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from hil.config import Config
from hil.twin.replay import Reading, Replayed, replay_closed_loop, replay_goals
from hil.twin.runs import FORCE_SIGNAL, SIGNALS, RecordedRun

if TYPE_CHECKING:
    from matplotlib.figure import Figure


class Loop(enum.StrEnum):
    OPEN = "open loop"
    CLOSED = "closed loop"


class Emulator(enum.StrEnum):
    TWIN = "twin"
    DEFAULT = "default"


@dataclass(frozen=True)
class Residual:
    run: str
    experiment: str
    controller: str
    loop: Loop
    emulator: Emulator
    joint: str
    signal: str
    unit: str
    mae: float
    rms: float
    ticks: int

    def record(self) -> dict[str, Any]:
        return {
            "run": self.run,
            "experiment": self.experiment,
            "controller": self.controller,
            "loop": self.loop.value,
            "emulator": self.emulator.value,
            "joint": self.joint,
            "signal": self.signal,
            "unit": self.unit,
            "mae": _finite(self.mae),
            "rms": _finite(self.rms),
            "ticks": self.ticks,
        }


def _finite(value: float) -> float | None:
    return value if math.isfinite(value) else None


def twin_of_run(twin: Config, run: RecordedRun) -> Config:
    """The run's own configuration with the twin's emulator."""
    return run.config.replaced(emulator=twin.emulator)


def residuals(
    run: RecordedRun, replayed: Replayed, loop: Loop, emulator: Emulator
) -> list[Residual]:
    out = []
    label = str(run.run.label)
    joints = run.joint_names
    for name, (unit, factor) in SIGNALS.items():
        recorded, got = run.signal(name), replayed.signal(name)
        for j, joint in enumerate(joints):
            out.append(_residual(run, label, loop, emulator, joint, name, unit, factor,
                                 recorded[:, j], got[:, j]))  # fmt: skip
    force = run.force()
    if force is not None and replayed.force_n is not None:
        out.append(
            _residual(run, label, loop, emulator, "", FORCE_SIGNAL, "N", 1.0, force,
                      replayed.force_n)
        )  # fmt: skip
    return out


def _residual(
    run: RecordedRun,
    label: str,
    loop: Loop,
    emulator: Emulator,
    joint: str,
    signal: str,
    unit: str,
    factor: float,
    recorded: np.ndarray,
    replayed: np.ndarray,
) -> Residual:
    both = np.isfinite(recorded) & np.isfinite(replayed)
    error = (replayed - recorded)[both] * factor
    mae = float(np.mean(np.abs(error))) if error.size else math.nan
    rms = float(np.sqrt(np.mean(error**2))) if error.size else math.nan
    return Residual(
        run.name, run.experiment_name, label, loop, emulator, joint, signal, unit, mae, rms,
        int(both.sum()),
    )  # fmt: skip


@dataclass
class CheckResult:
    residuals: list[Residual]
    figures: list[Path]
    report: Path

    def mae(
        self, *, emulator: Emulator, loop: Loop, signal: str, run: str | None = None
    ) -> list[float]:
        return [
            r.mae
            for r in self.residuals
            if r.emulator is emulator and r.loop is loop and r.signal == signal
            and (run is None or r.run == run)
        ]  # fmt: skip


def check_twin(
    twin: Config, runs: list[RecordedRun], out_dir: Path, *, closed_loop: bool = True
) -> CheckResult:
    """Replay every run on the twin and on its default emulator; report.md, check.json and a
    figure per run into out_dir."""
    out_dir.mkdir(parents=True, exist_ok=True)
    found: list[Residual] = []
    figures: list[Path] = []
    for run in runs:
        twin_config = twin_of_run(twin, run)
        traces: dict[tuple[Loop, Emulator], Replayed] = {}
        for emulator, config in ((Emulator.TWIN, twin_config), (Emulator.DEFAULT, run.config)):
            traces[(Loop.OPEN, emulator)] = replay_goals(config, run, Reading.DRIVERS)
            if closed_loop and not run.open_loop:
                traces[(Loop.CLOSED, emulator)] = replay_closed_loop(config, run)
        for (loop, emulator), replayed in traces.items():
            found += residuals(run, replayed, loop, emulator)
        figures.append(_figure(run, traces, out_dir))
        if len(run.joint_names) > 1:
            figures.append(_joints_figure(run, found, out_dir))
    result = CheckResult(found, figures, out_dir / "report.md")
    result.report.write_text(report_markdown(result, runs))
    from hil.output.strict_json import dumps

    (out_dir / "check.json").write_text(
        dumps({"residuals": [r.record() for r in found]}, indent=2) + "\n"
    )
    return result


def table(result: CheckResult) -> str:
    """Per run and signal, MAE (rms) of the twin beside the default emulator's, both loops."""
    rows: dict[tuple[str, str, str], dict[tuple[Loop, Emulator], Residual]] = {}
    for r in result.residuals:
        rows.setdefault((r.run, r.joint, r.signal), {})[(r.loop, r.emulator)] = r
    header = (
        "| run | controller | joint | signal | open loop: twin | default | closed loop: twin "
        "| default |"
    )
    lines = [header, "|---|---|---|---|---|---|---|---|"]
    for (run, joint, signal), cells in rows.items():
        first = next(iter(cells.values()))

        def cell(loop: Loop, emulator: Emulator, cells: dict = cells) -> str:
            r = cells.get((loop, emulator))
            if r is None or not math.isfinite(r.mae):
                return "-"
            return f"{r.mae:.3g} ({r.rms:.3g}) {r.unit}"

        lines.append(
            f"| {run} | {first.controller} | {joint or '-'} | {signal} | "
            f"{cell(Loop.OPEN, Emulator.TWIN)} | {cell(Loop.OPEN, Emulator.DEFAULT)} | "
            f"{cell(Loop.CLOSED, Emulator.TWIN)} | {cell(Loop.CLOSED, Emulator.DEFAULT)} |"
        )
    return "\n".join(lines)


def report_markdown(result: CheckResult, runs: list[RecordedRun]) -> str:
    links = "\n".join(f"![{p.stem}]({p.name})" for p in result.figures)
    return (
        "# The twin's replays against the record\n\n"
        "Each cell: mean absolute error (rms) of replayed - recorded over the run's ticks. "
        "Open loop: the recorded goals sent again; closed loop: the recorded controller on "
        "the recorded experiment. Twin: the twin's [emulator]; default: the run's own "
        "configuration's.\n\n"
        f"{table(result)}\n\n{links}\n"
    )


def _figure(run: RecordedRun, traces: dict[tuple[Loop, Emulator], Replayed], out: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    loop = Loop.CLOSED if (Loop.CLOSED, Emulator.TWIN) in traces else Loop.OPEN
    names = list(SIGNALS) + ([FORCE_SIGNAL] if run.force() is not None else [])
    time = run.run.time_s
    fig, axes = plt.subplots(len(names), 1, figsize=(9, 2.2 * len(names)), sharex=True)
    for axis, name in zip(np.atleast_1d(axes), names, strict=True):
        unit, factor = SIGNALS.get(name, ("N", 1.0))
        recorded = run.force() if name == FORCE_SIGNAL else run.signal(name)[:, 0]
        axis.plot(time, factor * recorded, "k", lw=1.2, label="recorded")
        for emulator, style in ((Emulator.TWIN, "C0--"), (Emulator.DEFAULT, "C3:")):
            replayed = traces[(loop, emulator)]
            got = replayed.force_n if name == FORCE_SIGNAL else replayed.signal(name)[:, 0]
            if got is not None:
                axis.plot(time, factor * got, style, lw=1.0, label=f"{emulator} ({loop})")
        axis.set_ylabel(f"{name}\n[{unit}]", fontsize=8)
    np.atleast_1d(axes)[0].legend(fontsize=8, loc="upper right")
    np.atleast_1d(axes)[-1].set_xlabel("time [s]")
    fig.suptitle(f"{run.name}: recorded vs replayed", fontsize=10)
    return _save(fig, out / f"{run.name}.png")


def _joints_figure(run: RecordedRun, found: list[Residual], out: Path) -> Path:
    """A robot of several joints at a glance: each joint's link-angle MAE, twin beside default,
    each loop (log scale: the two may differ by decades)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    joints = list(run.joint_names)
    mine = [r for r in found if r.run == run.name and r.signal == "link_angle_rad"]
    loops = [loop for loop in Loop if any(r.loop is loop for r in mine)]
    fig, axes = plt.subplots(len(loops), 1, figsize=(10, 2.8 * len(loops)), squeeze=False)
    x = np.arange(len(joints))
    for axis, loop in zip(axes[:, 0], loops, strict=True):
        bars = ((-0.2, Emulator.TWIN, "C0"), (0.2, Emulator.DEFAULT, "C3"))
        for offset, emulator, colour in bars:
            by_joint = {r.joint: r.mae for r in mine if r.loop is loop and r.emulator is emulator}
            heights = [by_joint.get(j, np.nan) for j in joints]
            axis.bar(x + offset, heights, 0.4, color=colour, label=str(emulator))
        axis.set_yscale("log")
        axis.set_xticks(x, joints, rotation=45, fontsize=7)
        axis.set_ylabel(f"link angle MAE\n[mrad], {loop}", fontsize=8)
        axis.legend(fontsize=8)
    fig.suptitle(f"{run.name}: each joint's link-angle error, twin vs default", fontsize=10)
    return _save(fig, out / f"{run.name}-joints.png")


def _save(fig: Figure, path: Path) -> Path:
    """Laid out and written whole or not at all (hil.output.plots.save_figure), then closed."""
    import matplotlib.pyplot as plt

    from hil.output.plots import save_figure

    fig.tight_layout()
    try:
        return save_figure(fig, path, dpi=90)
    finally:
        plt.close(fig)
