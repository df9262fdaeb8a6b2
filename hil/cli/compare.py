"""`hil compare RUN_DIR RUN_DIR... [--out DIR]`: any runs of one experiment side by side.

Overlays the runs (the experiment's own comparison figure when it is a built-in one, the
signals of every joint, on the humanoid the ZMP, pelvis tilt and support margin of
kinematics.csv), prints their metrics in one table with how each ended (a safety stop and
when; a missing or torn summary.json) and writes report.md with the figures into --out
(default runs/TIMESTAMP-compare-EXPERIMENT): hil/session/compare_runs.py. Reads the run
directories only; nothing is sent to any device.

Exit status: 0 compared; 2 a path that is not a run directory, runs of different experiments
(named), fewer than two runs or one given twice.
"""

from __future__ import annotations

import argparse
import sys

from hil.cli.exit_codes import ExitCode
from hil.session.compare_runs import NotComparable, compare_runs


def cmd_compare(args: argparse.Namespace) -> int:
    try:
        comparison = compare_runs(args.runs, args.out)
    except NotComparable as exc:
        print(f"hil compare: {exc}", file=sys.stderr)
        return ExitCode.USAGE
    print(comparison.table_text)
    return ExitCode.OK
