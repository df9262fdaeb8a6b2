"""`hil identify LOG_DIR... [--json] [--config F] [--figure PATH]`: the joint's constants from
identification runs (`hil run identify`), with 95 % intervals, a fit-quality figure and a
configuration fragment to paste.

What the fit is told rather than finds (hil/identify, "What these encoders cannot identify"):
the link's inertia and gravity moment ([model] link_inertia_kg_m2, gravity_moment_kg_m of the
configuration: --config FILE, else the configuration the run recorded in its meta.json), the
actuator's torque constant (a device fact: the drivers' units of the configured model) and its
current limit (the Torque Limit the run read from the actuator, in summary.json).

Output: a table per joint, the fragment, the figure next to the first log (identification.png;
identification.json and identification.toml beside it); with --json the last stdout line is
the result as JSON (`hil.identify.result_to_json`; several joints: the first joint's at the
top, every joint's under "joints"). Exit 2 for a directory that is not an identification run
(the message says what is missing), 1 if a fit fails.
"""

from __future__ import annotations

import argparse
import hashlib
import math
import os
import sys
from pathlib import Path
from typing import Any

from drivers.dynamixel import model_number, model_spec
from hil.cli.exit_codes import ExitCode
from hil.config import Config, ConfigError, config_from_record, load_config
from hil.identify import (
    IdentificationOptions,
    IdentificationResult,
    KnownJointFigures,
    LogFormatError,
    Parameter,
    render_config_fragment,
    result_to_json,
    write_identification_figure,
)
from hil.identify import identify as fit_joint
from hil.identify.runs import (
    IdentificationRun,
    NotAnIdentificationRun,
    read_identification_run,
    validation_start_of,
)
from hil.output.strict_json import dumps


def configuration(path: Path | None, run: IdentificationRun) -> Config:
    """--config FILE, else the configuration the run recorded, else the built-in one."""
    if path is not None:
        return load_config(path)
    record = run.run.meta.get("config")
    if isinstance(record, dict):
        try:
            return config_from_record(record)
        except ConfigError:
            pass  # an older layout: the built-in figures below, and the user is told
    print(
        f"hil identify: {run.out_dir} records no usable configuration; using the built-in "
        "one (give --config FILE)",
        file=sys.stderr,
    )
    return load_config(None)


def known_figures(config: Config, joint: str, current_limit_a: float | None) -> KnownJointFigures:
    """What the fit is told about `joint` ("" for a single-joint run: the first joint)."""
    section = next((j for j in config.joints if j.name == joint), config.joints[0])
    chain = next(d for d in config.dynamixel if d.name == config.chain_of(section))
    units = model_spec(model_number(chain.model)).units
    return KnownJointFigures(
        link_inertia_kg_m2=config.model.link_inertia_kg_m2,
        gravity_moment_kg_m=config.model.gravity_moment_kg_m,
        torque_constant_nm_per_a=units.torque_constant_nm_per_a,
        current_limit_a=current_limit_a,
    )


def result_table(result: IdentificationResult) -> str:
    """The identified figures, their intervals and the held-out fit quality, as text."""
    lines = [f"{'parameter':38s} {'value':>11s} {'95 % interval':>25s}  {'unit':10s} status"]
    for parameter, estimate in result.parameters.items():
        interval = f"[{_number(estimate.low)}, {_number(estimate.high)}]"
        lines.append(
            f"{parameter.value:38s} {_number(estimate.value):>11s} {interval:>25s}  "
            f"{parameter.unit:10s} {estimate.status.value}"
            + (f" ({estimate.note})" if estimate.note else "")
        )
    lines.append("held-out fit quality:")
    for quality in result.quality:
        lines.append(
            f"  {quality.model} / {quality.signal}: VAF {quality.vaf_percent:.2f} %, "
            f"NRMSE {quality.nrmse_percent:.1f} %"
        )
    lines += [f"note: {note}" for note in result.notes]
    return "\n".join(lines)


def _number(value: float) -> str:
    return f"{value:.5g}" if math.isfinite(value) else ("-" if math.isnan(value) else "inf")


def _figure_path(args: argparse.Namespace, first: Path, joint: str, several: bool) -> Path:
    """--figure FILE (FILE-JOINT.png per joint with several), --figure DIR (DIR's
    identification.png: a directory gets a file inside it), else the first log's."""
    suffix = f"-{joint}" if several and joint else ""
    figure = None if args.figure is None else Path(args.figure)
    if figure is not None and str(args.figure).endswith(os.sep):
        figure.mkdir(parents=True, exist_ok=True)  # DIR/: a directory, made if need be
    if figure is None or figure.is_dir():
        return (first if figure is None else figure) / f"identification{suffix}.png"
    return figure.with_name(f"{figure.stem}{suffix}{figure.suffix or '.png'}")


def _duplicates(paths: list[Path]) -> list[str]:
    """Runs given more than once (the same directory by any path, or a copy of one: the same
    log): each would be counted as an independent run and narrow the 95 % intervals."""
    seen: dict[object, Path] = {}
    repeated = []
    for path in paths:
        keys: list[object] = [os.path.realpath(path)]
        log = path / "log.csv"
        if log.is_file():
            keys.append(_digest(log))
        first = next((seen[key] for key in keys if key in seen), None)
        if first is not None:
            repeated.append(f"{path} (the same run as {first})")
        for key in keys:
            seen.setdefault(key, path)
    return repeated


def _digest(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _fit_all(
    args: argparse.Namespace, runs: list[IdentificationRun], config: Config
) -> dict[str, tuple[IdentificationResult, Path]]:
    joints = list(runs[0].logs)
    start = validation_start_of(runs)
    options = IdentificationOptions(validation_start_s=start)
    results = {}
    for joint in joints:
        limits = {run.current_limit_a[joint] for run in runs}
        limit = limits.pop() if len(limits) == 1 else None
        known = known_figures(config, joint, limit)
        result = fit_joint([run.logs[joint] for run in runs], known, options)
        figure = write_identification_figure(
            result, _figure_path(args, runs[0].out_dir, joint, len(joints) > 1)
        )
        results[joint] = (result, figure)
    return results


def _print_results(
    results: dict[str, tuple[IdentificationResult, Path]], runs: list[IdentificationRun]
) -> dict[str, Any]:
    records: dict[str, Any] = {}
    fragments = []
    for joint, (result, figure) in results.items():
        title = f"joint {joint}" if joint else "the joint"
        print(f"{title}: identified from {', '.join(result.sources)}")
        print(result_table(result))
        kp = result[Parameter.SERVO_KP].value
        kpp = result[Parameter.POSITION_GAIN].value
        print(
            f"Kp of (4) = {kp:.3g} 1/s is the best first-order fit at this band and amplitude; "
            f"the servo's position gain is {kpp:.3g} 1/s (they differ by the gearbox friction)"
        )
        print(f"figure: {figure}")
        fragment = render_config_fragment(result, joint or "")
        fragments.append(fragment)
        records[joint] = {**result_to_json(result), "joint": joint, "figure": str(figure)}
    text = "\n".join(fragments)
    print("\nconfiguration fragment (paste into your configuration file):\n")
    print(text)
    first = runs[0].out_dir
    (first / "identification.toml").write_text(text)
    (first / "identification.json").write_text(dumps(records, indent=2) + "\n")
    return records


def cmd_identify(args: argparse.Namespace) -> int:
    repeated = _duplicates([Path(p) for p in args.logs])
    if repeated:
        print(
            f"hil identify: {'; '.join(repeated)}: each run counts once (a run given twice "
            "would narrow the intervals as if it were two)",
            file=sys.stderr,
        )
        return ExitCode.USAGE
    try:
        runs = [read_identification_run(path) for path in args.logs]
    except NotAnIdentificationRun as exc:
        print(f"hil identify: {exc}", file=sys.stderr)
        return ExitCode.USAGE
    for note in (note for run in runs for note in run.run.notes):  # e.g. a torn last row
        print(f"hil identify: note: {note}", file=sys.stderr)
    joints = [tuple(run.logs) for run in runs]
    if len(set(joints)) != 1:
        print(
            f"hil identify: the runs are of different joints ({joints}): fit one robot's runs",
            file=sys.stderr,
        )
        return ExitCode.USAGE
    config = configuration(args.config, runs[0])
    try:
        results = _fit_all(args, runs, config)
    except LogFormatError as exc:
        print(f"hil identify: {exc}", file=sys.stderr)
        return ExitCode.USAGE
    records = _print_results(results, runs)
    if args.json:
        first = next(iter(records.values()))
        out = {**first, "joints": records} if len(records) > 1 else first
        print(dumps(out))
    return ExitCode.OK
