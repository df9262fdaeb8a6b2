"""`hil bench sweep`: runs per minute through the sweep's engine with 1 and 2 Ray workers (the
ratio is the scaling), and the engine's per-run overhead against a plain loop over the same
runs in this process.

The runs: the impact experiment with `pid`, shortened to RUN_DURATION_S, at `runs` servo gains
(distinct run ids, the same work each), on the in-process emulated testbed - what a sweep runs.
Ray is started once with 2 CPUs; then, per repeat, interleaved (this machine is shared and its
load drifts; the order is reversed every other repeat): a plain loop calling the worker's
function (`run_task`) in this process, Ray with at most 1 task in flight (1 worker busy), and
Ray with 2. Ray's start and one warm-up task per worker (a worker's first task imports MuJoCo
and the stack; the plain loop gets one too) are timed apart and left out of the rates: a long
sweep pays them once. The overhead per run is Ray's 1-worker time per run minus the plain
loop's, and Ray's time minus the runs' own time measured inside the workers. The machine's load
average is printed with the figures: the 2-worker rate is only as good as the second core is
free.
"""

from __future__ import annotations

import os
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from hil.config import Config
from hil.sweep.engine import import_ray, start_ray
from hil.sweep.plan import plan
from hil.sweep.processes import descendants, shutdown_ray_started_here
from hil.sweep.spec import SweepSpec, Task, parse_spec
from hil.sweep.task import FAILED, run_task

DEFAULT_RUNS = 8
DEFAULT_REPEATS = 2
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


def _checked(row: dict[str, Any]) -> dict[str, Any]:
    if row["ending"] == FAILED:
        raise RuntimeError(f"a bench run failed: {row['error']}")
    return row


def _plain(tasks: list[Task], root: Path) -> tuple[float, float]:
    """(elapsed, the runs' own time) of a plain loop over the tasks in this process."""
    started = time.perf_counter()
    inside = sum(_checked(run_task(task, str(root)))["wall_time_s"] for task in tasks)
    return time.perf_counter() - started, inside


def _on_ray(
    ray: Any, remote: Any, tasks: list[Task], root: Path, workers: int
) -> tuple[float, float]:
    """(elapsed, the runs' own time) with at most `workers` tasks in flight."""
    started = time.perf_counter()
    queue, in_flight, inside = list(tasks), [], 0.0
    while queue or in_flight:
        while queue and len(in_flight) < workers:
            in_flight.append(remote.remote(queue.pop(0), str(root)))
        ready, in_flight = ray.wait(in_flight, num_returns=1)
        inside += _checked(ray.get(ready[0]))["wall_time_s"]
    return time.perf_counter() - started, inside


MODES = ("plain", "ray_1", "ray_2")


def _measure(tasks: list[Task], root: Path, repeats: int, say: Callable[[str], None]) -> dict:
    """Ray started once with 2 CPUs; per repeat, the plain loop and Ray with 1 and with 2
    tasks in flight, interleaved (the order reversed every other repeat)."""
    ray = import_ray()
    figures: dict[str, Any] = {mode: [0.0, 0.0] for mode in MODES}
    started = time.perf_counter()
    before = descendants(os.getpid())
    try:
        start_ray(2, None)  # inside: a Ctrl-C held during the start comes right after it
        initialised = time.perf_counter()
        remote = ray.remote(num_cpus=1, max_retries=0)(run_task)
        ray.get([remote.remote(task, str(root / "warm-up")) for task in tasks[:2]])
        _checked(run_task(tasks[0], str(root / "warm-up-plain")))
        warmed = time.perf_counter()
        for repeat in range(repeats):
            for mode in MODES if repeat % 2 == 0 else tuple(reversed(MODES)):
                say(f"  repeat {repeat + 1}/{repeats}: {mode}, {len(tasks)} runs")
                where = root / f"{mode}-{repeat}"
                if mode == "plain":
                    elapsed, inside = _plain(tasks, where)
                else:
                    elapsed, inside = _on_ray(ray, remote, tasks, where, int(mode[-1]))
                figures[mode][0] += elapsed
                figures[mode][1] += inside
    finally:
        shutdown_ray_started_here(ray, before)
    return {"figures": figures, "init_s": initialised - started, "warm_up_s": warmed - initialised}


def run_bench_sweep(
    config: Config,
    runs: int = DEFAULT_RUNS,
    say: Callable[[str], None] = lambda _: None,
    repeats: int = DEFAULT_REPEATS,
) -> dict[str, Any]:
    """The figures as a dict (see `sweep_report_text`)."""
    tasks = plan(bench_spec(runs), config)
    with tempfile.TemporaryDirectory(prefix="hil-bench-sweep-") as tmp:
        measured = _measure(tasks, Path(tmp), repeats, say)
    total = runs * repeats
    elapsed = {mode: f[0] for mode, f in measured["figures"].items()}
    inside = {mode: f[1] for mode, f in measured["figures"].items()}
    rate = {mode: 60 * total / elapsed[mode] for mode in MODES}
    return {
        "runs": runs,
        "repeats": repeats,
        "load_average_1min": os.getloadavg()[0],
        "cpus": os.cpu_count(),
        "run": f"impact, pid, {RUN_DURATION_S:g} s, in-process emulated testbed",
        "runs_per_minute": rate,
        "scaling_2_over_1": rate["ray_2"] / rate["ray_1"],
        "seconds_per_run": {mode: elapsed[mode] / total for mode in MODES},
        "seconds_inside_run": {mode: inside[mode] / total for mode in MODES},
        "overhead_per_run_s": {
            "ray_1_vs_plain": (elapsed["ray_1"] - elapsed["plain"]) / total,
            "ray_1_vs_inside": (elapsed["ray_1"] - inside["ray_1"]) / total,
        },
        "ray_start_s": measured["init_s"],
        "warm_up_s": measured["warm_up_s"],
    }


def sweep_report_text(report: dict[str, Any]) -> str:
    rate, per_run = report["runs_per_minute"], report["seconds_per_run"]
    overhead = report["overhead_per_run_s"]
    names = {"plain": "plain loop", "ray_1": "Ray, 1 worker", "ray_2": "Ray, 2 workers"}
    return "\n".join(
        [
            f"hil bench sweep: {report['runs']} runs x {report['repeats']} repeats of "
            f"{report['run']}; {report['cpus']} CPUs, load average "
            f"{report['load_average_1min']:.1f}",
            f"{'':16s} {'runs/min':>9s} {'s/run':>7s}",
            *(f"{names[m]:16s} {rate[m]:9.1f} {per_run[m]:7.3f}" for m in MODES),
            f"scaling 2 workers / 1: {report['scaling_2_over_1']:.2f}x",
            f"engine overhead per run: {1e3 * overhead['ray_1_vs_plain']:+.0f} ms against the "
            f"plain loop, {1e3 * overhead['ray_1_vs_inside']:+.0f} ms against the runs' own time",
            f"Ray start {report['ray_start_s']:.1f} s, first task per worker "
            f"{report['warm_up_s']:.1f} s (not in the rates)",
        ]
    )
