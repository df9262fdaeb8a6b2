"""`hil bench sweep`: runs per minute through the sweep's engine with 1 and 2 Ray workers (the
ratio is the scaling), and the engine's per-run overhead against a plain loop over the same
runs in this process.

The runs: the impact experiment with `pid`, shortened to RUN_DURATION_S, at `runs` servo gains
(distinct run ids, the same work each), on the in-process emulated testbed - what a sweep runs.
Three measurements, one after another on the same runs: a plain loop calling the worker's
function (`run_task`) here; Ray with 1 CPU; Ray with 2 CPUs. Ray's start (`ray.init`) and one
warm-up task per worker (a worker's first task imports MuJoCo and the stack) are timed apart
and left out of the rates: a long sweep pays them once. The overhead per run is the Ray 1-CPU
time per run minus the plain loop's; and, less sensitive to the machine's load drifting between
the measurements, Ray's time per run minus the runs' own time measured inside the workers.
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from hil.config import Config
from hil.sweep.engine import import_ray, start_ray
from hil.sweep.spec import SweepSpec, Task, parse_spec, plan
from hil.sweep.task import FAILED, run_task

DEFAULT_RUNS = 8
RUN_DURATION_S = 2.5


def bench_spec(runs: int) -> SweepSpec:
    gains = ", ".join(f"{8.0 + 4.0 * i / max(runs - 1, 1):.4f}" for i in range(runs))
    return parse_spec(
        f"""
title = "bench"
experiments = ["impact"]
controllers = ["pid"]
duration_s = {RUN_DURATION_S}
[sampling]
method = "grid"
[[parameter]]
name = "Kp"
targets = ["emulator.servo.position_gain_per_s"]
values = [{gains}]
""",
        "bench",
    )


def _plain(tasks: list[Task], root: Path) -> tuple[float, float]:
    started = time.perf_counter()
    inside = sum(_checked(run_task(task, str(root)))["wall_time_s"] for task in tasks)
    return time.perf_counter() - started, inside


def _checked(row: dict[str, Any]) -> dict[str, Any]:
    if row["ending"] == FAILED:
        raise RuntimeError(f"a bench run failed: {row['error']}")
    return row


def _on_ray(tasks: list[Task], root: Path, cpus: int) -> dict[str, float]:
    ray = import_ray()
    started = time.perf_counter()
    start_ray(cpus, None)
    try:
        initialised = time.perf_counter()
        remote = ray.remote(num_cpus=1, max_retries=0)(run_task)
        warm = [remote.remote(task, str(root / "warm-up")) for task in tasks[:cpus]]
        ray.get(warm)
        warmed = time.perf_counter()
        rows = ray.get([remote.remote(task, str(root)) for task in tasks])
        done = time.perf_counter()
    finally:
        ray.shutdown()
    inside = sum(_checked(row)["wall_time_s"] for row in rows)
    return {
        "init_s": initialised - started,
        "warm_up_s": warmed - initialised,
        "elapsed_s": done - warmed,
        "inside_s": inside,
    }


def run_bench_sweep(
    config: Config, runs: int = DEFAULT_RUNS, say: Callable[[str], None] = lambda _: None
) -> dict[str, Any]:
    """The figures as a dict (see `sweep_report_text`)."""
    tasks = plan(bench_spec(runs), config)
    with tempfile.TemporaryDirectory(prefix="hil-bench-sweep-") as tmp:
        root = Path(tmp)
        say(f"plain loop: {runs} runs ...")
        plain_s, plain_inside = _plain(tasks, root / "plain")
        ray = {}
        for cpus in (1, 2):
            say(f"Ray, {cpus} CPU(s): {runs} runs ...")
            ray[cpus] = _on_ray(tasks, root / f"ray{cpus}", cpus)
    rate = {
        "plain": 60 * runs / plain_s,
        **{f"ray_{c}": 60 * runs / figures["elapsed_s"] for c, figures in ray.items()},
    }
    return {
        "runs": runs,
        "run": f"impact, pid, {RUN_DURATION_S:g} s, in-process emulated testbed",
        "runs_per_minute": rate,
        "scaling_2_over_1": rate["ray_2"] / rate["ray_1"],
        "seconds_per_run": {
            "plain": plain_s / runs,
            "plain_inside_run": plain_inside / runs,
            "ray_1": ray[1]["elapsed_s"] / runs,
            "ray_1_inside_run": ray[1]["inside_s"] / runs,
        },
        "overhead_per_run_s": {
            "ray_1_vs_plain": (ray[1]["elapsed_s"] - plain_s) / runs,
            "ray_1_vs_inside": (ray[1]["elapsed_s"] - ray[1]["inside_s"]) / runs,
        },
        "ray_start_s": {f"{c}_cpu": f["init_s"] for c, f in ray.items()},
        "warm_up_s": {f"{c}_cpu": f["warm_up_s"] for c, f in ray.items()},
    }


def sweep_report_text(report: dict[str, Any]) -> str:
    rate, per_run = report["runs_per_minute"], report["seconds_per_run"]
    overhead = report["overhead_per_run_s"]
    return "\n".join(
        [
            f"hil bench sweep: {report['runs']} runs of {report['run']}",
            f"{'':22s} {'runs/min':>9s} {'s/run':>8s}",
            f"{'plain loop':22s} {rate['plain']:9.1f} {per_run['plain']:8.3f}",
            f"{'Ray, 1 worker':22s} {rate['ray_1']:9.1f} {per_run['ray_1']:8.3f}",
            f"{'Ray, 2 workers':22s} {rate['ray_2']:9.1f} {60 / rate['ray_2']:8.3f}",
            f"scaling 2 workers / 1: {report['scaling_2_over_1']:.2f}x",
            f"engine overhead per run: {1e3 * overhead['ray_1_vs_plain']:+.0f} ms against the "
            f"plain loop, {1e3 * overhead['ray_1_vs_inside']:+.0f} ms against the runs' own time",
            "Ray start {:.1f} s / {:.1f} s, first task per worker {:.1f} s / {:.1f} s "
            "(1 / 2 workers; not in the rates)".format(
                report["ray_start_s"]["1_cpu"],
                report["ray_start_s"]["2_cpu"],
                report["warm_up_s"]["1_cpu"],
                report["warm_up_s"]["2_cpu"],
            ),
        ]
    )
