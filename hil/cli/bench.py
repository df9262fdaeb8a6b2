"""`hil bench bus|loop|pacing|log|soak|sweep [--json] [--cycles N] [--runs N] [--config F]`:
measure, print the figures."""

from __future__ import annotations

import argparse
import json
import sys

from drivers.joint_bus import BusError
from hil.bench.bus import DEFAULT_BUS_CYCLES, bus_report_text, run_bench_bus
from hil.bench.common import BenchError, without_nan
from hil.bench.log import DEFAULT_LOG_TICKS, log_report_text, run_bench_log
from hil.bench.loop import DEFAULT_LOOP_TICKS, loop_report_text, run_bench_loop
from hil.bench.pacing import (
    DEFAULT_PACING_PAIRS,
    DEFAULT_PACING_TICKS,
    pacing_report_text,
    run_bench_pacing,
)
from hil.bench.soak import DEFAULT_SOAK_TICKS, run_soak, soak_report_text
from hil.cli.common import checked_config
from hil.cli.exit_codes import ExitCode
from hil.wiring.emulation import EmulatorStartError

# A measurement keeps every cycle's figures: at most a million cycles (~1.5 h of ticks at 200 Hz,
# ~8 MB a series); --runs at most 100 runs (pairs) of a measurement; --seed as a TOML integer.
MAX_CYCLES = 1_000_000
MAX_RUNS = 100
MAX_SEED = 2**63 - 1


def _bench_sweep(args: argparse.Namespace) -> int:
    """`hil bench sweep [--runs N] [--json]`: the sweep engine's throughput and overhead."""
    from hil.sweep import RayMissing, import_ray
    from hil.sweep.bench import DEFAULT_RUNS, run_bench_sweep, sweep_report_text

    runs = args.runs or DEFAULT_RUNS
    if not 2 <= runs <= MAX_RUNS:
        print(f"hil bench sweep: --runs must be in 2..{MAX_RUNS}, got {runs}", file=sys.stderr)
        return ExitCode.USAGE
    try:
        import_ray()
    except RayMissing as exc:
        print(f"hil bench sweep: {exc}", file=sys.stderr)
        return ExitCode.USAGE
    config = checked_config(args.config)

    def say(text: str) -> None:
        if not args.json:
            print(text, file=sys.stderr, flush=True)

    report = run_bench_sweep(config, runs, say=say)
    print(
        json.dumps(without_nan(report), allow_nan=False) if args.json else sweep_report_text(report)
    )
    return ExitCode.OK


def cmd_bench(args: argparse.Namespace) -> int:
    """`hil bench bus|loop|pacing|log|soak [--json] [--cycles N] [--seed S] [--runs N]`; soak
    exits 1 when a reaction missed its bound, a row was lost or an exit state was misreported."""
    if args.what == "sweep":
        return _bench_sweep(args)
    cycles = args.cycles
    for option, value, low, high in (
        ("--cycles", cycles, 1, MAX_CYCLES),
        ("--seed", args.seed, 0, MAX_SEED),
        ("--runs", args.runs, 1, MAX_RUNS),
    ):
        if value is not None and not low <= value <= high:
            print(
                f"hil bench: {option} must be >= {low} and <= {high}, got {value}",
                file=sys.stderr,
            )
            return ExitCode.USAGE
    config = checked_config(args.config, args.robot)

    def say(text: str) -> None:
        if not args.json:
            print(text, file=sys.stderr, flush=True)

    try:
        if args.what == "bus":
            report = run_bench_bus(config, cycles or DEFAULT_BUS_CYCLES, say=say)
            text = bus_report_text(report)
        elif args.what == "log":
            bar = False if args.json else None  # None: a bar when stderr is a terminal
            report = run_bench_log(config, cycles or DEFAULT_LOG_TICKS, say=say, progress=bar)
            text = log_report_text(report)
        elif args.what == "loop":
            report = run_bench_loop(config, cycles or DEFAULT_LOOP_TICKS, say=say)
            text = loop_report_text(report)
        elif args.what == "pacing":
            pairs = args.runs or DEFAULT_PACING_PAIRS
            report = run_bench_pacing(config, cycles or DEFAULT_PACING_TICKS, pairs, say=say)
            text = pacing_report_text(report)
        else:
            report = run_soak(config, cycles or DEFAULT_SOAK_TICKS, seed=args.seed, say=say)
            text = soak_report_text(report)
    except (EmulatorStartError, BenchError, BusError, OSError) as exc:
        print(f"hil bench {args.what}: {exc}", file=sys.stderr)
        return ExitCode.FAILED
    print(json.dumps(without_nan(report), allow_nan=False) if args.json else text)
    if args.what == "soak" and not (report["all_within_bound"] and report["rows_lost"] == 0):
        return ExitCode.FAILED
    return ExitCode.OK
