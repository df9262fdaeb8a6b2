"""A sweep's plan judged before Ray starts: its size, then every point's configuration, once.

`checked_plan(spec, base)` is what `run_sweep` runs:
1. the run count from the spec alone (grid sizes or the Monte Carlo count, times experiments
   and controllers), refused above MAX_SWEEP_RUNS before a single point is listed;
2. the plan (hil/sweep/plan.py);
3. every point's configuration built as a worker builds it (`config_at`) and checked like a
   configuration file, the emulator's figures and the devices' included (`check_devices`),
   each controller's Kdist against [safety] max_kdist, the run's duration: a value the
   configuration refuses is a bad spec (exit 2), not a sweep of runs that fail one by one.
About 0.5 ms a point on the project's 2-core machine (a 100,000-point grid: ~50 s).
"""

from __future__ import annotations

import math

from hil.config import Config, ConfigError, config_from_record
from hil.loop import duration_problem
from hil.sweep.plan import config_at, plan, resolved
from hil.sweep.ranges import SpecError
from hil.sweep.spec import Sampling, SweepSpec, Task, parse_controller
from hil.wiring import check_devices

# A sweep plans at most this many runs: at ~15 runs per minute and CPU (`hil bench sweep`:
# short impact runs) a week of a 10-CPU machine. A larger study is several sweeps (or a
# Monte Carlo sample of the same space).
MAX_SWEEP_RUNS = 100_000


def point_count(spec: SweepSpec) -> int:
    """How many points the spec samples, without listing them."""
    if spec.sampling is Sampling.MONTE_CARLO:
        return spec.count
    sizes = [len(p.values) if p.values else (p.points or 0) for p in spec.parameters]
    return math.prod(sizes)


def run_count(spec: SweepSpec) -> int:
    """How many runs the spec plans (points x experiments x controllers)."""
    return point_count(spec) * len(spec.experiments) * len(spec.controllers)


def check_size(spec: SweepSpec) -> None:
    runs = run_count(spec)
    if runs > MAX_SWEEP_RUNS:
        raise SpecError(
            f"{runs} runs ({point_count(spec)} points x {len(spec.experiments)} experiments x "
            f"{len(spec.controllers)} controllers) is more than a sweep may plan "
            f"({MAX_SWEEP_RUNS}): use fewer points, or a Monte Carlo sample ([sampling] method "
            '= "monte-carlo", count = N)'
        )


def checked_plan(spec: SweepSpec, base: Config) -> list[Task]:
    """The plan, sized and with every point's configuration checked (module docstring)."""
    spec = resolved(spec, base)
    check_size(spec)
    if spec.duration_s is not None and (problem := duration_problem(spec.duration_s)):
        raise SpecError(f"duration_s: {problem}")
    tasks = plan(spec, base)
    if not tasks:
        return tasks
    planned = config_from_record(tasks[0].config_record)  # with [base] applied
    kdists = [parse_controller(c) for c in spec.controllers]
    bad: list[str] = []
    seen: set[str] = set()
    for task in tasks:
        if task.point_id in seen:
            continue
        seen.add(task.point_id)
        try:
            config = config_at(planned, task.targets, task.model)
            check_devices(config)
            limit = config.safety.max_kdist
            for choice in kdists:
                if choice.uses_kdist and choice.kdist > limit:
                    raise SpecError(
                        f"controller {choice.label}: Kdist {choice.kdist:g} is above [safety] "
                        f"max_kdist = {limit:g}"
                    )
        except (ConfigError, SpecError, ValueError, TypeError) as exc:
            where = ", ".join(f"{target} = {value!r}" for target, value in task.targets.items())
            bad.append(f"{task.values} ({where}): {exc}")
    if bad:
        raise SpecError(
            f"{len(bad)} of {len(seen)} points make a configuration hil refuses, the first at "
            f"{bad[0]}"
        )
    return tasks
