"""Running a sweep on Ray, resumably, and writing what it found.

`run_sweep(spec, base, out_dir, ...)`:
1. plans every run (hil/sweep/plan.py; a signal meanwhile stops it: `SweepInterrupted`, nothing
   written);
2. locks `out_dir` for this sweep alone (hil/sweep/lock.py: another sweep there is `SweepBusy`),
   checks that it holds this sweep's results or none (hil/sweep/identity.py: another base
   configuration, spec setting or code version is `SweepMismatch`, naming what differs) and
   reads results.csv: the runs whose ids it holds are done (a failed run too: it is a result)
   and are not run again;
3. runs the rest as Ray tasks (`ray.init()` on this machine with `workers` CPUs, or joining the
   cluster at `address`), at most two per CPU in flight; each finished run's row is appended to
   results.csv at once, with progress and an ETA on stderr;
4. checks the paper's relations at every point (hil/sweep/relations.py), writes relations.csv,
   the maps (maps/*.png) and summary.json, and returns the fractions.
Ctrl-C or SIGTERM at any moment after the plan (before Ray is up, while it starts, while the
runs go, while it shuts down) stops the sweep without losing what finished: the runs in flight
are cancelled (their rows are not written, so a rerun does them), Ray is shut down, and the
findings and summary.json are written for the rows there are (hil/sweep/interrupts.py).
Ray is an optional dependency (`pip install -e '.[sweep]'`); without it `RayMissing` says so.
"""

from __future__ import annotations

import csv
import logging
import os
import socket
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hil.config import Config
from hil.output.strict_json import dumps
from hil.sweep.checks import checked_plan
from hil.sweep.identity import claim
from hil.sweep.interrupts import SweepSignals, sigint_held
from hil.sweep.lock import locked
from hil.sweep.maps import write_maps
from hil.sweep.plan import distinct_runs, identity_of, resolved
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
POLL_S = 0.25  # how often the wait for a finished run looks at the signals


class SweepInterrupted(RuntimeError):
    """A signal came while the plan was being made: nothing was run or written."""


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
    signal: str | None = None  # the first signal received during the sweep, if any
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
            "signal": self.signal,
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
    `address`. A terminal's Ctrl-C meanwhile waits for the start to end, and reaches only
    this process, not Ray's processes started here (hil/sweep/interrupts.py)."""
    ray = import_ray()
    if ray.is_initialized():
        return
    quiet: dict[str, Any] = {"logging_level": logging.ERROR, "log_to_driver": False}
    if address:
        check_reachable(address)
        ray.init(address=address, **quiet)
        return
    adopt_orphans()  # an agent whose raylet died anyway comes to us, to be ended at shutdown
    with sigint_held():
        ray.init(num_cpus=workers, include_dashboard=False, **quiet)


def execute_on_ray(
    tasks: Sequence[Task],
    table: ResultsTable,
    out_dir: Path,
    ray: Any,
    say: Callable[[str], None],
    signals: SweepSignals,
) -> int:
    """Run the tasks on Ray, appending each row when it is done, until they are done or a
    signal comes (the runs in flight are then cancelled); the rows written."""
    remote = ray.remote(num_cpus=1, max_retries=0)(run_task)
    cpus = max(1, int(ray.cluster_resources().get("CPU", 1)))
    queue = deque(tasks)
    in_flight: dict[Any, Task] = {}
    progress = Progress(len(tasks), say)
    written = 0
    while (queue or in_flight) and signals.reason is None:
        while queue and len(in_flight) < IN_FLIGHT_PER_CPU * cpus:
            task = queue.popleft()
            in_flight[remote.remote(task, str(out_dir))] = task
        ready, _ = ray.wait(list(in_flight), num_returns=1, timeout=POLL_S)
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
    for ref in in_flight:
        ray.cancel(ref, force=True)
    return written


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
    signals = SweepSignals()
    signals.install()
    try:
        try:
            with signals.raising():
                spec = resolved(spec, base)
                tasks = checked_plan(spec, base)
                identity = identity_of(spec, base)
        except KeyboardInterrupt:
            raise SweepInterrupted(
                f"interrupted ({signals.reason or 'SIGINT'}) while the plan was made: nothing "
                f"was run, {out_dir} is as it was"
            ) from None
        out_dir = Path(out_dir)
        with locked(out_dir):
            claim(out_dir, identity, spec.name)
            table = ResultsTable(out_dir, header(spec.parameter_names, spec.experiments))
            runs = distinct_runs(tasks)
            pending = [t for t in runs if t.run_id not in table]
            outcome = SweepOutcome(out_dir, len(runs), len(runs) - len(pending))
            shared = len(tasks) - len(runs)
            say(
                f"hil sweep {spec.name}: {len(runs)} runs ({len(spec.points())} points x "
                f"{len(spec.experiments)} experiments x {len(spec.controllers)} controllers"
                + (f", {shared} of them the same run as another: run once" if shared else "")
                + f"); {outcome.done_before} done before, {len(pending)} to run -> {out_dir}"
            )
            if max_runs is not None:
                pending = pending[:max_runs]
            if pending and signals.reason is None:
                outcome.done_now = _run_on_ray(pending, table, signals, workers, address, say)
            outcome.signal = signals.reason
            outcome.interrupted = signals.reason is not None
            done = [table.rows[t.run_id] for t in runs if t.run_id in table]
            outcome.failed = sum(1 for row in done if row["ending"] == FAILED)
            outcome.wall_time_s = time.perf_counter() - started
            write_findings(spec, point_rows(tasks, table), outcome)
            return outcome
    finally:
        signals.restore()


def _run_on_ray(
    pending: Sequence[Task],
    table: ResultsTable,
    signals: SweepSignals,
    workers: int | None,
    address: str | None,
    say: Callable[[str], None],
) -> int:
    """Start Ray (unless it is up), run the pending tasks, shut down a Ray started here; the
    rows written. A signal at any moment ends it with Ray shut down (module docstring)."""
    ray = import_ray()
    started_here = not ray.is_initialized()
    before = descendants(os.getpid())
    try:
        with signals.while_ray_starts():
            start_ray(workers, address)
        if signals.reason is not None:
            return 0
        return execute_on_ray(pending, table, table.path.parent, ray, say, signals)
    finally:  # also after a start cut short: no Ray process left behind
        if started_here:
            shutdown_ray_started_here(ray, before, hurry=lambda: signals.hurried)


def point_rows(tasks: Sequence[Task], table: ResultsTable) -> list[dict[str, Any]]:
    """The row of every (point, experiment, controller) whose run is done, as that point's: a
    run two of them share was written once, with the first one's values (hil/sweep/plan.py); a
    point drawn twice is one point."""
    rows: dict[tuple[str, str, str], dict[str, Any]] = {}
    for t in tasks:
        key = (t.point_id, t.experiment, t.controller)
        if t.run_id in table and key not in rows:
            ours = {**t.values, "point_id": t.point_id, "controller": t.controller}
            rows[key] = {**table.rows[t.run_id], **ours}
    return list(rows.values())


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
    summary = outcome.out_dir / "summary.json"
    written = summary.with_suffix(".json.tmp")
    written.write_text(dumps(outcome.record(spec), indent=2) + "\n")
    os.replace(written, summary)  # never a half-written summary.json


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
