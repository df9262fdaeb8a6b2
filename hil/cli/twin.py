"""`hil twin RUN_DIR... --out twin.toml` and `hil twin --check twin.toml RUN_DIR...`: the bench's
twin fitted from its recorded runs, and its replays of (held-out) runs against the record.

Fit (hil/twin/fit.py): the emulator's figures of the testbed's joint - K, D, the servo's
cascade, the rotor, the gearbox's friction (its model chosen on the held-out samples), the
link's inertia and gravity moment, the motor encoder's zero - each with its 95 % interval, the
pairs the data cannot separate, the link encoder's zero and delay as estimated; written as a
configuration file (the runs' recorded configuration with that [emulator]: `hil emulate
--config twin.toml`, `hil run ... --config twin.toml --emulate`). DYROS-JET's legs
(hil/twin/legs.py): the same figures for each of the twelve joints (a table per joint) and the
robot's mass scale, from `hil run suspended-chirp` (and a run on the feet, e.g. `push`, for
what hanging cannot show). --workers N: replays N at a time; --ray (or --address ADDR): as
tasks on a local Ray or a cluster. Exit 0: written; 1: the fit cannot be trusted (each reason
on stderr; nothing written unless --force, which writes it with the reasons in its header and
still exits 1); 2: a directory that is not a run, runs of different robots, a robot the twin
does not fit, Ray missing or its cluster unreachable.

Check (hil/twin/check.py): each run replayed on the twin and on its default emulator, open and
closed loop; the table of MAE (rms) per run, joint and signal, and report.md, check.json and a
figure per run in --out (default: runs/TIMESTAMP-twin-check). Exit 0, or 2 for bad input.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from hil.cli.exit_codes import ExitCode
from hil.config import ConfigError, load_config
from hil.output.rundir import timestamp
from hil.output.strict_json import dumps
from hil.vocabulary import Robot

if TYPE_CHECKING:
    from hil.config import Config
    from hil.twin.fit import TwinFit
    from hil.twin.legs import LegsFit
    from hil.twin.runs import RecordedRun


def add_twin(sub: argparse._SubParsersAction) -> None:
    twin = sub.add_parser(
        "twin",
        help="fit the emulator to your bench's recorded runs; replay runs on it (--check)",
        description="Fit the emulator's figures (gear, servo, friction model, link, encoder "
        "zeros) to recorded runs of one robot and write them as a configuration file; with "
        "--check TWIN, replay runs on that twin and on the default emulator and report the "
        "residual per joint and signal.",
    )
    twin.add_argument("runs", nargs="+", type=Path, metavar="RUN_DIR", help="run directories")
    twin.add_argument(
        "--out", type=Path, help="fit: the twin's file (default twin.toml); --check: the "
        "report's directory (default runs/TIMESTAMP-twin-check)",
    )  # fmt: skip
    twin.add_argument("--check", type=Path, metavar="TWIN", help="replay RUN_DIRs on this twin")
    twin.add_argument(
        "--open-loop", action="store_true", help="--check: the open-loop replays only"
    )
    twin.add_argument(
        "--workers", type=int, default=1,
        help="fit: replays at a time (processes; with --ray, the local Ray's CPUs)",
    )  # fmt: skip
    twin.add_argument(
        "--ray", action="store_true",
        help="fit: the replays as Ray tasks (a local Ray of --workers CPUs, or --address)",
    )  # fmt: skip
    twin.add_argument("--address", help="fit: the replays on the Ray cluster at this address")
    twin.add_argument(
        "--force", action="store_true", help="fit: write the twin even if it cannot be trusted"
    )
    twin.add_argument("--json", action="store_true", help="last stdout line: the result as JSON")


def cmd_twin(args: argparse.Namespace) -> int:
    from hil.twin.runs import NotATwinRun, read_runs

    if args.workers < 1:
        print("hil twin: --workers must be at least 1", file=sys.stderr)
        return ExitCode.USAGE
    try:
        runs = read_runs(args.runs)
    except NotATwinRun as exc:
        print(f"hil twin: {exc}", file=sys.stderr)
        return ExitCode.USAGE
    if args.check is not None:
        return _check(args, runs)
    return _fit(args, runs)


def _fit(args: argparse.Namespace, runs: list[RecordedRun]) -> int:
    from hil.sweep.engine import ClusterUnreachable, RayMissing
    from hil.twin.fit import CHANNELS, FitOptions, fit_twin, link_delay_s

    out = args.out or Path("twin.toml")
    if out.is_dir():
        print(f"hil twin: --out {out} is a directory; name the twin's file", file=sys.stderr)
        return ExitCode.USAGE
    if runs[0].config.model.robot is Robot.DYROS_JET:
        return _fit_legs(args, runs, out)
    try:
        fit = fit_twin(runs, FitOptions(workers=args.workers, ray=_ray_of(args)), say=_say)
    except (ValueError, RayMissing, ClusterUnreachable) as exc:
        print(f"hil twin: {exc}", file=sys.stderr)
        return ExitCode.USAGE
    if fit.estimates:
        fit.estimates["link_encoder_delay_s"] = link_delay_s(runs, fit.config)
    print(f"the twin of {', '.join(str(r.out_dir) for r in runs)}:")
    print(_estimates_table(fit))
    print("gearbox friction, by the held-out samples:")
    for score in fit.scores:
        mark = "  <- chosen" if score.model is fit.friction else ""
        print(
            f"  {score.model.value:16s} held-out cost {score.held_out_cost:.4g}, link angle "
            f"{1e3 * score.held_out_link_rms_rad:.3g} mrad rms{mark}"
        )
    held = fit.held_out_rms or {c: math.nan for c in CHANNELS}
    print(
        f"held out: motor angle {1e3 * held['motor_angle_rad']:.3g} mrad, link angle "
        f"{1e3 * held['link_angle_rad']:.3g} mrad, current {held['motor_current_a']:.3g} A rms"
    )
    for a, b, rho in fit.correlations:
        print(f"  the data hardly separate {a} and {b} (correlation {rho:+.3f})")
    for note in fit.notes:
        print(f"note: {note}")
    header = [
        f"The twin of {', '.join(r.name for r in runs)}, fitted by `hil twin` (hil/twin/fit.py).",
        f"gearbox friction: {fit.friction.value}; held-out link angle "
        f"{1e3 * held['link_angle_rad']:.3g} mrad rms.",
        *(f"{k} = {e.value:.6g} {e.unit} (95 % {e.low:.6g} .. {e.high:.6g})"
          for k, e in fit.estimates.items()),
    ]  # fmt: skip
    _write_unless_untrusted(args, fit.config, fit.problems, out, header)
    if args.json:
        print(dumps(_fit_json(fit, out)))
    return ExitCode.FAILED if fit.problems else ExitCode.OK


def _write_unless_untrusted(
    args: argparse.Namespace, config: Config, problems: list[str], out: Path, header: list[str]
) -> None:
    """Each reason not to trust the fit on stderr; the twin written if there is none (or with
    --force, the reasons in its header)."""
    from hil.twin.toml_file import write_config

    for problem in problems:
        print(f"hil twin: CANNOT BE TRUSTED: {problem}", file=sys.stderr)
    if problems and not args.force:
        print("hil twin: no twin written (--force writes it anyway)", file=sys.stderr)
        return
    write_config(config, out, header + [f"NOT TRUSTED: {p}" for p in problems])
    print(f"twin: {out}  (hil emulate --config {out}; hil run ... --config {out} --emulate)")


def _fit_legs(args: argparse.Namespace, runs: list[RecordedRun], out: Path) -> int:
    """DYROS-JET's legs (hil/twin/legs.py): a table per joint, the same exits as the testbed's."""
    from hil.sweep.engine import ClusterUnreachable, RayMissing
    from hil.twin.legs import LegsFitOptions, fit_legs

    try:
        options = LegsFitOptions(workers=args.workers, ray=_ray_of(args))
        fit = fit_legs(runs, options, say=_say)
    except (ValueError, RayMissing, ClusterUnreachable) as exc:
        print(f"hil twin: {exc}", file=sys.stderr)
        return ExitCode.USAGE
    print(f"the legs' twin of {', '.join(str(r.out_dir) for r in runs)}:")
    print(_legs_table(fit))
    mass = fit.estimates.get("mass_scale")
    if mass:
        e = mass[0]
        print(f"mass_scale {e.value:.4g} (95 % {e.low:.4g} .. {e.high:.4g})")
    for note in fit.notes:
        print(f"note: {note}")
    header = [
        f"The legs' twin of {', '.join(r.name for r in runs)}, fitted by `hil twin` "
        "(hil/twin/legs.py).",
        "held-out link angle rms per joint [mrad]: "
        + ", ".join(f"{1e3 * v:.3g}" for v in fit.held_out_rms["link_angle_rad"]),
        "gearbox friction per joint: " + ", ".join(m.value for m in fit.figures.models),
    ]
    _write_unless_untrusted(args, fit.config, fit.problems, out, header)
    if args.json:
        print(dumps(_legs_json(fit, out)))
    return ExitCode.FAILED if fit.problems else ExitCode.OK


# The legs' table: a column per figure (its value, and its 95 % half-width in % or mrad).
_LEGS_COLUMNS = (
    ("gear_stiffness_nm_per_rad", "K", 1.0),
    ("gear_damping_nms_per_rad", "D", 1.0),
    ("position_gain_per_s", "Kpp", 1.0),
    ("velocity_gain_nms_per_rad", "kv", 1.0),
    ("velocity_integral_time_s", "Ti", 1.0),
    ("motor_reflected_inertia_kg_m2", "Jm", 1.0),
    ("gearbox_coulomb_friction_nm", "Fc", 1.0),
    ("gearbox_viscous_friction_nms_per_rad", "Fv", 1.0),
    ("motor_zero_error_rad", "motor0 mrad", 1e3),
    ("link_zero_error_rad", "link0 mrad", 1e3),
)


def _legs_table(fit: LegsFit) -> str:
    names = fit.config.joint_names
    head = f"{'joint':12s}" + "".join(f"{label:>16s}" for _, label, _ in _LEGS_COLUMNS)
    lines = [head + f"{'friction':>17s}{'held-out mrad':>15s}"]
    for j, name in enumerate(names):
        cells = []
        for key, _, factor in _LEGS_COLUMNS:
            e = fit.estimates[key][j]
            if factor != 1.0:
                cells.append(f"{factor * e.value:8.3g} +-{factor * (e.high - e.low) / 2:<5.2g}")
            else:
                cells.append(f"{e.value:8.4g} +-{100 * e.relative_half_width:3.0f}%")
        held = 1e3 * fit.held_out_rms["link_angle_rad"][j]
        lines.append(
            f"{name:12s}" + "".join(f"{c:>16s}" for c in cells)
            + f"{fit.figures.models[j].value:>17s}{held:15.3g}"
        )  # fmt: skip
    return "\n".join(lines)


def _legs_json(fit: LegsFit, out: Path) -> dict[str, Any]:
    return {
        "twin": str(out),
        "trusted": fit.trusted,
        "joints": list(fit.config.joint_names),
        "friction_models": [m.value for m in fit.figures.models],
        "figures": {
            key: [
                {"value": _num(e.value), "low": _num(e.low), "high": _num(e.high), "unit": e.unit}
                for e in estimates
            ]
            for key, estimates in fit.estimates.items()
        },
        "friction_scores": {m.value: [float(v) for v in s] for m, s in fit.scores.items()},
        "held_out_rms": {c: [float(v) for v in rms] for c, rms in fit.held_out_rms.items()},
        "iterations": fit.iterations,
        "problems": fit.problems,
    }


def _ray_of(args: argparse.Namespace) -> str | None:
    """FitOptions.ray: None (no Ray), "" (a local Ray), or the cluster's address."""
    if args.address:
        return str(args.address)
    return "" if args.ray else None


def _say(text: str) -> None:
    print(f"hil twin: {text}", file=sys.stderr, flush=True)


def _estimates_table(fit: TwinFit) -> str:
    lines = [f"{'figure':40s} {'value':>12s} {'95 % interval':>27s}  unit"]
    for key, e in fit.estimates.items():
        interval = f"[{e.low:.5g}, {e.high:.5g}]"
        note = f"  ({e.note})" if e.note else ""
        lines.append(f"{key:40s} {e.value:12.6g} {interval:>27s}  {e.unit}{note}")
    return "\n".join(lines)


def _fit_json(fit: TwinFit, out: Path) -> dict[str, Any]:
    return {
        "twin": str(out),
        "trusted": fit.trusted,
        "friction_model": fit.friction.value,
        "figures": {
            k: {
                "value": _num(e.value),
                "low": _num(e.low),
                "high": _num(e.high),
                "unit": e.unit,
                "fitted": e.fitted,
            }
            for k, e in fit.estimates.items()
        },
        "friction_scores": {s.model.value: s.held_out_cost for s in fit.scores},
        "held_out_rms": fit.held_out_rms,
        "correlations": [list(c) for c in fit.correlations],
        "problems": fit.problems,
    }


def _num(value: float) -> float | None:
    return value if math.isfinite(value) else None


def _check(args: argparse.Namespace, runs: list[RecordedRun]) -> int:
    from hil.twin.check import check_twin, table

    try:
        twin = load_config(args.check)
    except ConfigError as exc:
        print(f"hil twin: --check {args.check}: {exc}", file=sys.stderr)
        return ExitCode.USAGE
    out = args.out or Path("runs") / f"{timestamp()}-twin-check"
    result = check_twin(twin, runs, out, closed_loop=not args.open_loop)
    print(table(result))
    print(f"report: {result.report}")
    if args.json:
        print(
            dumps(
                {"report": str(result.report), "residuals": [r.record() for r in result.residuals]}
            )
        )
    return ExitCode.OK
