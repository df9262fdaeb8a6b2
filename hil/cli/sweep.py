"""`hil sweep SPEC [--address ADDR] [--workers N] [--out DIR] [--list] [--json] [--config F]
[--max-runs N]`: a grid or Monte Carlo sweep of runs on Ray, resumable, with the fraction of
the sampled space in which each of the paper's relations holds (hil/sweep).

The output directory defaults to runs/sweep-<spec name>, so rerunning the same command after
Ctrl-C resumes it. Exit status: 0 when every run of the plan is finished (a run that failed is
recorded and counted), 1 when interrupted (Ctrl-C or SIGTERM, at any moment) or incomplete, 2
for a bad spec, a bad option, no Ray installed, an output directory that holds another sweep's
results (another base configuration, spec settings or code: docs/sweep.md) or one another
sweep is writing to.
"""

from __future__ import annotations

import argparse
import sys
import tomllib
from pathlib import Path

from hil.cli.common import checked_config
from hil.cli.exit_codes import ExitCode
from hil.config import ConfigError
from hil.output.strict_json import dumps


def _list() -> int:
    from hil.sweep import shipped_specs

    for name, text in shipped_specs().items():
        title = tomllib.loads(text).get("title", "")
        print(f"{name:12s} {title}")
    return ExitCode.OK


def cmd_sweep(args: argparse.Namespace) -> int:
    if args.list:
        return _list()
    if args.spec is None:
        print("hil sweep: name a spec (a TOML file, or one of `hil sweep --list`)", file=sys.stderr)
        return ExitCode.USAGE
    from hil.session.plan import usable_cpus

    cpus = usable_cpus()
    if args.workers is not None and not 1 <= args.workers <= cpus:
        # the local Ray's CPUs are this machine's: more would run that many runs on too few
        # cores, each slower than its lock-step allowance
        print(
            f"hil sweep: --workers must be from 1 to the {cpus} CPUs this process may use, "
            f"got {args.workers}",
            file=sys.stderr,
        )
        return ExitCode.USAGE
    if args.max_runs is not None and args.max_runs < 0:
        print(f"hil sweep: --max-runs must be >= 0, got {args.max_runs}", file=sys.stderr)
        return ExitCode.USAGE
    from hil.sweep import (
        ClusterUnreachable,
        RayMissing,
        SpecError,
        SweepBusy,
        SweepInterrupted,
        SweepMismatch,
        TableMismatch,
        fractions_text,
        import_ray,
        load_spec,
        run_sweep,
    )

    try:
        import_ray()
        spec = load_spec(args.spec)
        config = checked_config(args.config)
        out_dir = args.out or Path("runs") / f"sweep-{spec.name}"
        outcome = run_sweep(
            spec,
            config,
            out_dir,
            workers=args.workers,
            address=args.address,
            max_runs=args.max_runs,
            say=lambda text: print(text, file=sys.stderr, flush=True),
        )
    except (
        RayMissing,
        SpecError,
        TableMismatch,
        ConfigError,
        ClusterUnreachable,
        SweepMismatch,
        SweepBusy,
    ) as exc:
        print(f"hil sweep: {exc}", file=sys.stderr)
        return ExitCode.USAGE
    except SweepInterrupted as exc:
        print(f"hil sweep: {exc}", file=sys.stderr)
        return ExitCode.FAILED
    print(f"{spec.title}")
    print(
        f"{outcome.done_before + outcome.done_now} of {outcome.total} runs finished "
        f"({outcome.done_now} now, {outcome.failed} failed) in {outcome.out_dir}"
    )
    print(fractions_text(outcome))
    for path in outcome.maps:
        print(f"map: {path}")
    if outcome.interrupted or not outcome.complete:
        why = f" ({outcome.signal})" if outcome.signal else ""
        print(f"incomplete{why}: rerun the same command to resume (finished runs are kept)")
    if args.json:
        print(dumps(outcome.record(spec)))
    return ExitCode.OK if outcome.complete else ExitCode.FAILED
