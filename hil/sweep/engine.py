"""Running a sweep on Ray, resumably, and writing what it found.

`run_sweep(spec, base, out_dir, ...)`:
1. plans every run (hil/sweep/plan.py) and reads results.csv in `out_dir`: the runs whose ids
   it holds are done (a failed run too: it is a result) and are not run again;
2. runs the rest as Ray tasks (`ray.init()` on this machine with `workers` CPUs, or joining the
   cluster at `address`), at most two per CPU in flight; each finished run's row is appended to
   results.csv at once, with progress and an ETA on stderr. Ctrl-C cancels the runs in flight
   (their rows are not written, so a rerun does them) and stops;
3. checks the paper's relations at every point (hil/sweep/relations.py), writes relations.csv,
   the maps (maps/*.png) and summary.json, and returns the fractions.
Ray is an optional dependency (`pip install -e '.[sweep]'`); without it `RayMissing` says so.
"""

from __future__ import annotations

import contextlib
import csv
import logging
import os
import signal
import socket
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hil.config import Config
from hil.output.strict_json import dumps
from hil.sweep.checks import checked_plan
from hil.sweep.maps import write_maps
from hil.sweep.plan import resolved
from hil.sweep.processes import adopt_orphans, descendants, shutdown_ray_started_here
from hil.sweep.relations import PointRelation, RelationFraction, fractions, point_relations
from hil.sweep.spec import Sampling, SweepSpec, Task
from hil.sweep.table import ResultsTable, header
from hil.sweep.task import FAILED, run_task, task_row
from hil.vocabulary import Termination

INSTALL_HINT = (
    "hil sweep runs on Ray, an optional dependency: pip install 'flexjoint-hil[sweep]' "
    "(in a checkout: pip install -e '.[sweep]')"
)
IN_FLIGHT_PER_CPU = 2
CONNECT_TIMEOUT_S = 5.0


class RayMissing(RuntimeError):
    """Ray is not installed (the message says how to install it)."""


class ClusterUnreachable(RuntimeError):
    """--address names a cluster nothing answers at (the message says where and why)."""


def check_reachable(address: str, timeout_s: float = CONNECT_TIMEOUT_S) -> None:
    """A TCP connection to HOST:PORT (or ray://HOST:PORT) within `timeout_s`, before Ray tries:
    `ray.init` retries an unreachable address for minutes, repeating its warnings. "auto" and
    an address without a port are left to Ray."""
    host, sep, port = address.removeprefix("ray://").rpartition(":")
    if not sep or not port.isdigit():
        return
    try:
        socket.create_connection((host.strip("[]") or "127.0.0.1", int(port)), timeout_s).close()
    except OSError as exc:
        raise ClusterUnreachable(
            f"--address {address}: cannot reach a Ray cluster there within {timeout_s:g} s "
            f"({exc.strerror or exc}); is `ray start --head` running on that machine, and is "
            "its port open?"
        ) from None


def import_ray() -> Any:
    try:
        import ray
    except ImportError:
        raise RayMissing(INSTALL_HINT) from None
    return ray


@dataclass
class SweepOutcome:
    out_dir: Path
    total: int
    done_before: int
    done_now: int = 0
    failed: int = 0
    interrupted: bool = False
    wall_time_s: float = 0.0
    fractions: list[RelationFraction] = field(default_factory=list)
    maps: list[Path] = field(default_factory=list)

    @property
    def complete(self) -> bool:
        return self.done_before + self.done_now == self.total

    def record(self, spec: SweepSpec) -> dict[str, Any]:
        return {
            "spec": spec.name,
            "title": spec.title,
            "out_dir": str(self.out_dir),
            "runs": self.total,
            "finished": self.done_before + self.done_now,
            "done_before": self.done_before,
            "done_now": self.done_now,
            "failed": self.failed,
            "complete": self.complete,
            "interrupted": self.interrupted,
            "wall_time_s": self.wall_time_s,
            "map_axes": list(spec.axes),
            "relations": [f.record() for f in self.fractions],
            "maps": [str(p) for p in self.maps],
        }


class Progress:
    """`[n/N] run -> ending (s) | runs/min | ETA` lines for the runs of this invocation."""

    def __init__(self, total: int, say: Callable[[str], None]) -> None:
        self.total, self.say = total, say
        self.done = 0
        self.started = time.perf_counter()

    def tick(self, row: dict[str, Any], values: dict[str, Any]) -> None:
        self.done += 1
        elapsed = time.perf_counter() - self.started
        rate = self.done / elapsed if elapsed > 0 else 0.0
        eta = (self.total - self.done) / rate if rate > 0 else float("inf")
        shown = ", ".join(f"{k}={_short(v)}" for k, v in values.items())
        self.say(
            f"[{self.done}/{self.total}] {row['experiment']} {row['controller']} ({shown}) -> "
            f"{row['ending']} ({row['wall_time_s']:.1f} s) | {60 * rate:.1f} runs/min | "
            f"ETA {_clock(eta)}"
        )


def _short(value: Any) -> str:
    return f"{value:.4g}" if isinstance(value, float) else str(value)


def _clock(seconds: float) -> str:
    if seconds == float("inf"):
        return "?"
    minutes, secs = divmod(int(round(seconds)), 60)
    return f"{minutes // 60}:{minutes % 60:02d}:{secs:02d}"


def start_ray(workers: int | None, address: str | None) -> None:
    """Ray, unless already initialised: local with `workers` CPUs, or the cluster at
    `address`."""
    ray = import_ray()
    if ray.is_initialized():
        return
    quiet: dict[str, Any] = {"logging_level": logging.ERROR, "log_to_driver": False}
    if address:
        check_reachable(address)
        ray.init(address=address, **quiet)
        return
    # A terminal's Ctrl-C goes to the whole foreground process group, Ray's own processes
    # included: the raylet would die on it and leave its agents behind. Started with SIGINT
    # ignored (inherited through exec), they leave the signal to this process, which cancels
    # the runs and shuts Ray down in order.
    main_thread = threading.current_thread() is threading.main_thread()
    adopt_orphans()  # an agent whose raylet died anyway comes to us, to be ended at shutdown
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if main_thread else None
    try:
        ray.init(num_cpus=workers, include_dashboard=False, **quiet)
    finally:
        if main_thread:
            signal.signal(signal.SIGINT, previous or signal.default_int_handler)


def execute_on_ray(
    tasks: Sequence[Task],
    table: ResultsTable,
    out_dir: Path,
    ray: Any,
    say: Callable[[str], None],
) -> tuple[int, bool]:
    """Run the tasks on Ray, appending each row when it is done; (rows written, interrupted)."""
    remote = ray.remote(num_cpus=1, max_retries=0)(run_task)
    cpus = max(1, int(ray.cluster_resources().get("CPU", 1)))
    queue = deque(tasks)
    in_flight: dict[Any, Task] = {}
    progress = Progress(len(tasks), say)
    written = 0
    try:
        while queue or in_flight:
            while queue and len(in_flight) < IN_FLIGHT_PER_CPU * cpus:
                task = queue.popleft()
                in_flight[remote.remote(task, str(out_dir))] = task
            ready, _ = ray.wait(list(in_flight), num_returns=1)
            for ref in ready:
                task = in_flight.pop(ref)
                try:
                    row = ray.get(ref)
                except ray.exceptions.RayError as exc:  # the worker died: a failed run
                    row = task_row(task, FAILED, False, error=f"{type(exc).__name__}: {exc}"[:500])
                if row["ending"] == Termination.INTERRUPTED.value:
                    continue  # not finished: a rerun does it again
                table.append(row)
                written += 1
                progress.tick(row, task.values)
    except KeyboardInterrupt:
        for ref in in_flight:
            ray.cancel(ref, force=True)
        return written, True
    return written, False


def run_sweep(
    spec: SweepSpec,
    base: Config,
    out_dir: Path,
    *,
    workers: int | None = None,
    address: str | None = None,
    max_runs: int | None = None,
    say: Callable[[str], None] = lambda text: None,
) -> SweepOutcome:
    """See the module docstring. max_runs: run at most this many of the pending runs (the
    rest stay pending, as after an interruption)."""
    started = time.perf_counter()
    if max_runs is not None and max_runs < 0:
        raise ValueError(f"max_runs must be >= 0, got {max_runs}")
    spec = resolved(spec, base)
    tasks = checked_plan(spec, base)
    out_dir = Path(out_dir)
    table = ResultsTable(out_dir, header(spec.parameter_names, spec.experiments))
    pending = [t for t in tasks if t.run_id not in table]
    outcome = SweepOutcome(out_dir, len(tasks), len(tasks) - len(pending))
    say(
        f"hil sweep {spec.name}: {len(tasks)} runs ({len(spec.points())} points x "
        f"{len(spec.experiments)} experiments x {len(spec.controllers)} controllers); "
        f"{outcome.done_before} done before, {len(pending)} to run -> {out_dir}"
    )
    if max_runs is not None:
        pending = pending[:max_runs]
    if pending:
        ray = import_ray()
        started_here = not ray.is_initialized()
        before = descendants(os.getpid())
        try:
            start_ray(workers, address)
            with terminate_as_interrupt():  # after ray.init, which sets its own SIGTERM exit
                done, interrupted = execute_on_ray(pending, table, out_dir, ray, say)
            outcome.done_now, outcome.interrupted = done, interrupted
        finally:  # also after Ctrl-C during ray.init: no Ray process left behind
            if started_here and ray.is_initialized():
                shutdown_ray_started_here(ray, before)
    rows = [table.rows[t.run_id] for t in tasks if t.run_id in table]
    outcome.failed = sum(1 for row in rows if row["ending"] == FAILED)
    outcome.wall_time_s = time.perf_counter() - started
    write_findings(spec, rows, outcome)
    return outcome


@contextlib.contextmanager
def terminate_as_interrupt() -> Iterator[None]:
    """SIGTERM stops the sweep as Ctrl-C does (the runs in flight cancelled, the rows kept, the
    findings written, Ray shut down), instead of Ray's handler exiting on the spot."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(_signum: int, _frame: object) -> None:
        raise KeyboardInterrupt("SIGTERM")

    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def write_findings(spec: SweepSpec, rows: list[dict[str, Any]], outcome: SweepOutcome) -> None:
    """relations.csv, maps/*.png and summary.json for the rows done so far."""
    found = point_relations(rows, spec.experiments, spec.parameter_names, spec.duration_s)
    outcome.fractions = fractions(found)
    _write_relations(outcome.out_dir / "relations.csv", found, spec.parameter_names)
    if found:
        outcome.maps = write_maps(
            outcome.out_dir,
            found,
            outcome.fractions,
            spec.axes,
            grid=spec.sampling is Sampling.GRID,
            title=spec.title,
        )
    summary = outcome.record(spec)
    (outcome.out_dir / "summary.json").write_text(dumps(summary, indent=2) + "\n")


def _write_relations(
    path: Path, found: Sequence[PointRelation], parameter_names: Sequence[str]
) -> None:
    with open(path, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["point_id", *parameter_names, "experiment", "claim", "verdict", "ours"])
        for item in found:
            r = item.relation
            values = [item.values.get(name) for name in parameter_names]
            writer.writerow([item.point_id, *values, r.experiment, r.claim, r.verdict, r.ours])


def fractions_text(outcome: SweepOutcome) -> str:
    """The fractions as a table for the terminal."""
    lines = [f"{'holds':>7s}  {'checked':>7s}  relation"]
    for f in outcome.fractions:
        share = "-" if f.fraction is None else f"{100 * f.fraction:5.1f} %"
        lines.append(f"{share:>7s}  {f.checked:7d}  {f.experiment}: {f.claim}")
    return "\n".join(lines)
