"""One run of a sweep, as a Ray worker (or a plain loop) executes it: `run_task(task, root)`.

The run goes through the same code as `hil run EXPERIMENT`: `Session.run_one` on a lock-step
setup (the in-process emulated testbed, or a `hil emulate` child on its emulated buses). Its
row is returned whatever happens: a run that raises, or whose configuration the point makes
invalid, comes back as a failed row with the error, never as nothing.
"""

from __future__ import annotations

import math
import shutil
import time
import traceback
from pathlib import Path
from typing import Any

from hil.config import config_from_record
from hil.output.strict_json import plain
from hil.robots import get_experiment
from hil.session import Session, Setup
from hil.sweep.plan import config_at
from hil.sweep.spec import SweepSetup, Task

FAILED = "failed"  # the row's `ending` when the run raised instead of ending
SETUPS = {SweepSetup.IN_PROCESS: Setup.IN_PROCESS, SweepSetup.EMBEDDED: Setup.EMBEDDED}


def task_row(task: Task, ending: str, ran_its_course: bool, **extra: Any) -> dict[str, Any]:
    """The row of results.csv for this task (metrics go in `metrics`, a dict)."""
    return {
        "run_id": task.run_id,
        "point_id": task.point_id,
        **task.values,
        "experiment": task.experiment,
        "controller": task.controller,
        "ending": ending,
        "ran_its_course": ran_its_course,
        "error": extra.get("error", ""),
        "wall_time_s": extra.get("wall_time_s", math.nan),
        "out_dir": extra.get("out_dir", ""),
        "metrics": extra.get("metrics", {}),
    }


def run_task(task: Task, root: str) -> dict[str, Any]:
    """Run one task into `root`/runs/<run_id>; its row (see `task_row`)."""
    started = time.perf_counter()
    out_dir = Path(root) / "runs" / task.run_id
    if out_dir.exists():
        shutil.rmtree(out_dir)  # a run interrupted before its row was written
    try:
        config = config_at(config_from_record(task.config_record), task.targets, task.model)
        session = Session(
            config,
            SETUPS[task.setup],
            seed=task.seed,
            out_root=out_dir.parent,
            plots=False,
            quiet=True,
        )
        result = session.run_one(
            get_experiment(task.experiment),
            task.choice,
            duration_s=task.duration_s,
            out_dir=out_dir,
            print_result=False,
        )
    except Exception as exc:  # noqa: BLE001 - recorded as a failed run, not lost
        detail = "".join(traceback.format_exception_only(type(exc), exc)).strip()
        return task_row(
            task,
            FAILED,
            False,
            error=detail,
            wall_time_s=time.perf_counter() - started,
            out_dir=str(out_dir) if out_dir.exists() else "",  # what it wrote, if anything
        )
    kept = task.keep_log or not result.termination.ran_its_course
    if not kept:
        shutil.rmtree(out_dir, ignore_errors=True)
    return task_row(
        task,
        result.ending.termination.value,
        result.termination.ran_its_course,
        error="" if result.ok else result.ending.detail,
        wall_time_s=time.perf_counter() - started,
        out_dir=str(out_dir) if kept else "",
        metrics=plain(result.metrics),
    )
