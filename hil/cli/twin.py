"""`hil twin RUN_DIR... --out twin.toml` and `hil twin --check twin.toml RUN_DIR...`: the bench's
twin fitted from its recorded runs, and its replays of (held-out) runs against the record.

Fit (hil/twin/fit.py): the emulator's figures of the testbed's joint - K, D, the servo's
cascade, the rotor, the gearbox's friction (its model chosen on the held-out samples), the
link's inertia and gravity moment, the motor encoder's zero - each with its 95 % interval, the
pairs the data cannot separate, the link encoder's zero and delay as estimated; written as a
configuration file (the runs' recorded configuration with that [emulator]: `hil emulate
--config twin.toml`, `hil run ... --config twin.toml --emulate`). Exit 0: written; 1: the fit
cannot be trusted (each reason on stderr; nothing written unless --force, which writes it with
the reasons in its header and still exits 1); 2: a directory that is not a run, runs of
different robots, a robot the twin does not fit yet.

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

if TYPE_CHECKING:
    from hil.twin.fit import TwinFit
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
    twin.add_argument("--workers", type=int, default=1, help="fit: replays at a time (processes)")
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
    from hil.twin.fit import CHANNELS, FitOptions, fit_twin, link_delay_s
    from hil.twin.toml_file import write_config

    out = args.out or Path("twin.toml")
    if out.is_dir():
        print(f"hil twin: --out {out} is a directory; name the twin's file", file=sys.stderr)
        return ExitCode.USAGE
    try:
        fit = fit_twin(runs, FitOptions(workers=args.workers), say=_say)
    except ValueError as exc:
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
    for problem in fit.problems:
        print(f"hil twin: CANNOT BE TRUSTED: {problem}", file=sys.stderr)
    if fit.problems and not args.force:
        print("hil twin: no twin written (--force writes it anyway)", file=sys.stderr)
    else:
        header += [f"NOT TRUSTED: {p}" for p in fit.problems]
        write_config(fit.config, out, header)
        print(f"twin: {out}  (hil emulate --config {out}; hil run ... --config {out} --emulate)")
    if args.json:
        print(dumps(_fit_json(fit, out)))
    return ExitCode.FAILED if fit.problems else ExitCode.OK


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
