"""`hil bench loop`: controller compute per tick, the lock-step real-time factor, and the 200 Hz
wall-clock loop's timing.

- controller compute per tick (hil/bench/compute.py: `step` + `notify_applied`) of all four
  controllers for 1 and 12 joints, interleaved tick by tick (on the humanoid: its 12 legs with
  the pinocchio gravity compensator, plus the LQR gain's rescheduling, Sm of (19) and the
  design, which runs off the 200 Hz path);
- the real-time factor of a lock-step run of the impact experiment (the humanoid: stand) with
  gc+lqr+dob through the emulated buses (`hil.loop.run_experiment`, the loop `hil run` uses):
  simulated s / wall s;
- the 200 Hz wall-clock loop (`hil.loop.WallClock`) running the same experiment against the
  emulator in realtime mode: measured period, lateness of each tick's start behind its grid
  time, slack, overruns and skipped ticks.
Figures print human-readable or as one JSON object; nothing here asserts a timing.
"""

from __future__ import annotations

import dataclasses
import math
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from controller import CONTROLLER_NAMES, ControllerKind
from drivers.tick_budget import tick_budget
from drivers.timing import DurationStats as Distribution
from hil.bench.bus import JOINT_COUNTS
from hil.bench.common import (
    BenchError,
    StartFailed,
    machine,
    termination_text,
    with_bench_reply_timeout,
    with_retries,
)
from hil.bench.compute import bench_controllers
from hil.bench.machine import bench_cpu_stalls, bench_idle_sleeper, stall_counts_longer_than
from hil.bench.reschedule import bench_gain_schedule, gain_schedule_lines
from hil.bench.speed import bench_speed, speed_text
from hil.config import Config
from hil.experiments import Experiment
from hil.loop import (
    LockstepClock,
    LoopClock,
    RunRequest,
    Tick,
    WallClock,
    robot_model,
    run_experiment,
)
from hil.output.records import RunResult
from hil.robots import profile_of
from hil.vocabulary import ControllerChoice, EmulatorClock
from hil.wiring import Connection, make_bus
from hil.wiring.emulation import EmbeddedEmulator, emulator_spec
from hil.wiring.hardware import bus_config

DEFAULT_LOOP_TICKS = 1000  # 5 s at 200 Hz: the whole impact experiment
LOOP_CONTROLLER = ControllerKind.GC_LQR_DOB
MIN_RUN_TICKS = 3  # a run that made fewer ticks did not get going


class RecordingClock(LoopClock):
    """Wraps the loop's clock and records, per tick, when it started (perf_counter) and what
    the clock said about it; preallocated, so recording costs no allocation in the loop.

    grid_origin_s: perf_counter just before the first tick was asked for, and again just
    before the grid was re-anchored at the end of the start-up tick (`start_grid`). The wall
    clock anchors its grid when that call arrives, so `started_s[k] - (grid_origin_s + index *
    period)` is the tick's lateness from tick 1 on, overstated (never understated) by the few
    microseconds a call takes to return.
    """

    def __init__(self, inner: LoopClock, capacity: int) -> None:
        super().__init__(inner.period_s)
        self.inner = inner
        self.grid_origin_s = math.nan
        self.started_s = np.full(capacity, math.nan)
        self.grid_index = np.full(capacity, -1, dtype=np.int64)
        self.measured_period_s = np.full(capacity, math.nan)
        self.slack_s = np.full(capacity, math.nan)
        self.skipped = np.zeros(capacity, dtype=np.int64)
        self.count = 0
        self._last_index = 0

    @property
    def deterministic(self) -> bool:
        return self.inner.deterministic

    def next_tick(self) -> Tick:
        if self.count == 0:
            self.grid_origin_s = time.perf_counter()
        tick = self.inner.next_tick()
        started = time.perf_counter()
        self._last_index = tick.index
        k = self.count
        if k < self.started_s.size:
            self.started_s[k] = started
            self.grid_index[k] = tick.index
            self.measured_period_s[k] = tick.measured_period_s
            self.slack_s[k] = tick.slack_s
            self.skipped[k] = tick.skipped
        self.count += 1
        return tick

    def start_grid(self) -> None:
        self.grid_origin_s = time.perf_counter() - self._last_index * self.period_s
        self.inner.start_grid()

    def recorded(self) -> slice:
        return slice(0, min(self.count, self.started_s.size))


@dataclass(frozen=True)
class _RunRecord:
    clock: RecordingClock
    result: RunResult
    timing_csv: Path  # the runner's per-tick timing
    latency_timer_ms: float  # the Dynamixel reply timeout's latency term the run used


def loop_experiment(base: Config) -> Experiment:
    """What the loop benches run: the robot's bench experiment (the testbed's impact, the
    humanoid standing)."""
    return profile_of(base).bench_experiment


def _run_impact(base: Config, ticks: int, realtime: bool, out_dir: Path) -> _RunRecord:
    """The loop experiment with gc+lqr+dob for `ticks` ticks, the way `hil run` runs it."""
    experiment = loop_experiment(base)
    period_s = base.loop.period_s
    clock_kind = EmulatorClock.REALTIME if realtime else EmulatorClock.LOCKSTEP
    spec = emulator_spec(base, experiment=experiment, clock=clock_kind)
    inner: LoopClock = (
        WallClock(period_s, spin_s=base.loop.spin_before_tick_s)
        if realtime
        else LockstepClock(period_s)
    )
    capacity = ticks + 2 * base.loop.stop_cycles + 1
    clock = RecordingClock(inner, capacity)
    request = RunRequest(
        experiment=experiment,
        choice=ControllerChoice(LOOP_CONTROLLER, base.controller.kdist),
        out_dir=out_dir,
        duration_s=ticks * period_s,
    )
    with EmbeddedEmulator(spec) as emulator:
        connection = Connection.from_endpoints(emulator.endpoints, base)
        bus_clock = inner.now if isinstance(inner, LockstepClock) else time.monotonic
        bus = make_bus(base, connection, clock=bus_clock)
        meta = {"bench": "hil bench loop", "clock": "wall" if realtime else "lockstep"}
        result = run_experiment(base, request, bus, clock, meta)
    if result.ticks < MIN_RUN_TICKS:
        raise StartFailed(f"the run ended after {result.ticks} tick(s): {result.ending}")
    latency_ms = bus.config.chains[0].latency_timer_ms
    return _RunRecord(clock, result, out_dir / "timing.csv", latency_ms)


def _tick_timing(timing_csv: Path) -> dict[str, Any]:
    """The runner's own per-tick timing (timing.csv): bus read, then controller + supervisor +
    bus write."""
    table = np.loadtxt(timing_csv, delimiter=",", skiprows=1, ndmin=2)
    read = Distribution.of(table[1:, 1])  # tick 0 also runs the start gate
    compute = Distribution.of(table[1:, 2])
    return {
        "bus_read": dataclasses.asdict(read),
        "compute_and_write": dataclasses.asdict(compute),
    }


def bench_lockstep_run(
    base: Config, ticks: int, out_dir: Path, say: Callable[[str], None] = lambda _text: None
) -> dict[str, Any]:
    """Real-time factor of the lock-step loop: simulated time / wall time, from the second tick
    (after the start gate and torque on) to the last; opening and closing the bus excluded."""
    record, failures = with_retries(
        "lock-step run", lambda: _run_impact(base, ticks, realtime=False, out_dir=out_dir), say
    )
    clock, result = record.clock, record.result
    started = clock.started_s[clock.recorded()]
    simulated_s = (started.size - 2) * clock.period_s
    wall_s = float(started[-1] - started[1])
    return {
        "experiment": loop_experiment(base).name,
        "controller": str(LOOP_CONTROLLER),
        "kdist": base.controller.kdist,
        "ticks": int(result.ticks),
        "termination": result.ending.text,
        "failed_starts": failures,
        "simulated_s": simulated_s,
        "loop_wall_s": wall_s,
        "real_time_factor": simulated_s / wall_s,
        "run_wall_s": float(result.wall_time_s),
        "tick": _tick_timing(record.timing_csv),
        "latency_timer_ms": record.latency_timer_ms,
    }


def bench_wall_clock(
    base: Config, ticks: int, out_dir: Path, say: Callable[[str], None] = lambda _text: None
) -> dict[str, Any]:
    """The 200 Hz WallClock loop against the realtime emulator: period and lateness statistics.

    lateness_k = (when tick k started) - (grid time of tick k), the grid anchored where the
    clock anchors it (see `RecordingClock`). Tick 0 (start gate, torque on) is left out of the
    statistics.
    """
    record, failures = with_retries(
        "wall-clock run", lambda: _run_impact(base, ticks, realtime=True, out_dir=out_dir), say
    )
    clock, result = record.clock, record.result
    recorded = clock.recorded()
    started = clock.started_s[recorded]
    grid = clock.grid_index[recorded]
    lateness = started - (clock.grid_origin_s + grid * clock.period_s)
    inner = clock.inner
    assert isinstance(inner, WallClock)
    # Tick 0 runs the start gate and turns torque on (tens of ms): the first period, lateness
    # and slack that measure a control tick are tick 2's (slack[k]: how tick k-1 ended).
    control = slice(2, None)
    slack = clock.slack_s[recorded]
    return {
        "experiment": loop_experiment(base).name,
        "controller": str(LOOP_CONTROLLER),
        "rate_hz": base.loop.rate_hz,
        "ticks": int(result.ticks),
        "termination": result.ending.text,
        "failed_starts": failures,
        "period": dataclasses.asdict(Distribution.of(clock.measured_period_s[recorded][control])),
        "lateness": dataclasses.asdict(Distribution.of(lateness[control])),
        "slack": dataclasses.asdict(Distribution.of(slack[control])),
        "overruns": int(np.count_nonzero(slack[control] < 0)),
        "skipped_ticks": int(clock.skipped[recorded][control].sum()),
        "overruns_with_start_tick": inner.stats.overruns,
        "tick": _tick_timing(record.timing_csv),
        "latency_timer_ms": record.latency_timer_ms,
    }


def run_bench_loop(
    config: Config,
    ticks: int = DEFAULT_LOOP_TICKS,
    *,
    joint_counts: Sequence[int] = JOINT_COUNTS,
    say: Callable[[str], None] = lambda _text: None,
) -> dict[str, Any]:
    # the wire budget of the configuration as given (the bench widens only its own timeout)
    budget = tick_budget(bus_config(config, Connection.from_config(config)), config.loop.period_s)
    config = with_bench_reply_timeout(config)
    own_joints = robot_model(config).rescheduled  # (bench_controllers: its own joints)
    sizes = "the robot's joints" if own_joints else f"{len(joint_counts)} sizes"
    say(f"bench loop: {len(CONTROLLER_NAMES)} controllers x {sizes}, {ticks} ticks interleaved ...")
    controllers = bench_controllers(config, ticks, joint_counts=joint_counts)
    schedule = bench_gain_schedule(config)
    name = loop_experiment(config).name
    say("bench loop: real-time factors through the buses, in process and of MuJoCo alone ...")
    speed = bench_speed(config, loop_experiment(config), LOOP_CONTROLLER, ticks, say=say)
    with tempfile.TemporaryDirectory(prefix="hil-bench-") as tmp:
        say(f"bench loop: lock-step {name} run with {LOOP_CONTROLLER}, {ticks} ticks ...")
        lockstep = bench_lockstep_run(config, ticks, Path(tmp) / "lockstep", say)
        say(
            f"bench loop: wall-clock {config.loop.rate_hz:g} Hz {name} run against the "
            f"realtime emulator, {ticks} ticks ({ticks * config.loop.period_s:g} s) ..."
        )
        try:
            wall = bench_wall_clock(config, ticks, Path(tmp) / "wall", say)
        except BenchError as exc:  # the other figures stand; say why this one is missing
            wall = {"error": str(exc), "rate_hz": config.loop.rate_hz}
    say(f"bench loop: an idle {config.loop.rate_hz:g} Hz sleeper as long (the machine's own) ...")
    sleeper = bench_idle_sleeper(config.loop.period_s, ticks)
    say("bench loop: a process that never sleeps, as long (when the CPU is taken from it) ...")
    stalls = bench_cpu_stalls(ticks * config.loop.period_s)
    return {
        "bench": "loop",
        "machine": machine(),
        "config": config.source,
        "period_s": config.loop.period_s,
        "tick_budget": {
            **dataclasses.asdict(budget),
            "sequential_s": budget.sequential_s,
            "overlapped_s": budget.overlapped_s,
            "text": budget.text(),
        },
        "controllers": controllers,
        "gain_schedule": schedule,
        "speed": speed,
        "lockstep_run": lockstep,
        "wall_clock_run": wall,
        "idle_sleeper": sleeper,
        "cpu_stalls": stalls,
    }


def loop_report_text(report: dict[str, Any]) -> str:
    period_ms = report["period_s"] * 1e3
    lines = [
        "hil bench loop",
        "",
        "controller compute per tick (step + notify_applied), all cases interleaved tick by tick:",
        f"  {'joints':>6}  {'controller':<11}  {'median [us]':>11}  {'p99 [us]':>9}  "
        f"{'max [us]':>9}  {'build [ms]':>10}",
    ]
    for case in report["controllers"]:
        lines.append(
            f"  {case['n_joints']:>6}  {case['controller']:<11}  {case['median_s'] * 1e6:>11.1f}"
            f"  {case['p99_s'] * 1e6:>9.1f}  {case['max_s'] * 1e6:>9.1f}  "
            f"{case['build_s'] * 1e3:>10.2f}"
        )
    schedule = report.get("gain_schedule")
    if schedule:
        lines += gain_schedule_lines(schedule)
    lines += [
        "",
        "the tick on a real robot's wires (drivers/tick_budget.py, from the configuration):",
    ]
    lines.append("  " + report["tick_budget"]["text"])
    lines += ["", *speed_text(report["speed"])]
    lock = report["lockstep_run"]
    lines += [
        "",
        f"lock-step run ({lock['experiment']}, {lock['controller']} Kdist {lock['kdist']:g}, "
        "through the emulated buses, log written):",
        f"  {lock['simulated_s']:.2f} s simulated in {lock['loop_wall_s']:.2f} s of loop: "
        f"real-time factor {lock['real_time_factor']:.2f} "
        f"(whole run incl. bus open/close {lock['run_wall_s']:.2f} s)",
        "  per tick median / p99 / max [ms]: bus read "
        + Distribution(**lock["tick"]["bus_read"]).text()
        + ", controller + supervisor + write "
        + Distribution(**lock["tick"]["compute_and_write"]).text(),
        *termination_text(lock),
    ]
    wall = report["wall_clock_run"]
    if "error" in wall:
        lines += ["", f"wall-clock run at {wall['rate_hz']:g} Hz: no figures: {wall['error']}"]
        return "\n".join(lines)
    lines += [
        "",
        f"wall-clock run at {wall['rate_hz']:g} Hz (nominal period {period_ms:g} ms) against the "
        f"realtime emulator, {wall['ticks']} ticks (reply timeout latency term "
        f"{wall['latency_timer_ms']:g} ms):",
        "  median / p99 / max [ms]:",
        f"    measured period  {Distribution(**wall['period']).text()}",
        f"    lateness         {Distribution(**wall['lateness']).text()}",
        f"    slack            min {wall['slack']['min_s'] * 1e3:.3f}, median "
        f"{wall['slack']['median_s'] * 1e3:.3f} (time left when a cycle finished; < 0: overrun)",
        f"    bus read         {Distribution(**wall['tick']['bus_read']).text()}",
        f"    compute + write  {Distribution(**wall['tick']['compute_and_write']).text()}",
        f"  overruns {wall['overruns']}, skipped ticks {wall['skipped_ticks']} (after the start "
        f"tick, which runs the start gate; with it: {wall['overruns_with_start_tick']} overruns)",
        *termination_text(wall),
    ]
    lines += _machine_text(report, wall)
    return "\n".join(lines)


def _machine_text(report: dict[str, Any], wall: dict[str, Any]) -> list[str]:
    """The idle sleeper and the CPU stalls beside the wall-clock run: how many of the stalls
    were longer than the loop's median slack (each that lands in a cycle overruns it)."""
    lines: list[str] = []
    sleeper = report.get("idle_sleeper")
    if sleeper:
        late = sleeper["late_by_more_than_s"]
        lines += [
            "",
            f"the machine itself: a loop that only sleeps to the same grid, {sleeper['ticks']} "
            "ticks (no bus, no emulator):",
            f"  wake-up lateness median / p99 / max [ms] "
            f"{Distribution(**sleeper['lateness']).text()}; later than 1 / 2 / 3 ms: "
            f"{late['0.001']} / {late['0.002']} / {late['0.003']} times",
        ]
    stalls = report.get("cpu_stalls")
    if not stalls:
        return lines
    longer = stalls["longer_than_s"]
    counts = " / ".join(str(longer[bound]["all"]) for bound in sorted(longer, key=float))
    bounds = " / ".join(f"{float(bound) * 1e3:g}" for bound in sorted(longer, key=float))
    taken = stalls["stalls"]["count"]
    longest = f", longest {stalls['stalls']['max_s'] * 1e3:.2f} ms" if taken else ""
    steal = stalls["steal_s_all_cpus"]
    steal_text = f"{steal * 1e3:.0f} ms" if steal is not None and math.isfinite(steal) else "n/a"
    lines.append(
        f"  a process that never sleeps, {stalls['duration_s']:g} s: the CPU was taken from it "
        f"{taken} times for >= 0.5 ms ({stalls['stalled_s'] * 1e3:.0f} ms in all{longest}); "
        f"longer than {bounds} ms: {counts} times; the kernel's steal time over all CPUs "
        f"{steal_text}"
    )
    slack = wall.get("slack", {}).get("median_s")
    if isinstance(slack, float) and math.isfinite(slack) and slack > 0:
        over = stall_counts_longer_than(stalls, slack)
        lines.append(
            f"  stalls longer than the loop's median slack ({slack * 1e3:.2f} ms): {over['all']}, "
            f"of which {over['outside']} from outside the OS (not waiting in its runqueue, not "
            f"blocked: a hypervisor or firmware), {over['runqueue']} the OS running another "
            f"task; each that lands in a cycle overruns it whatever the loop does"
        )
    wires_s = report["period_s"] - report["tick_budget"]["overlapped_s"]
    floor = stall_counts_longer_than(stalls, wires_s)
    lines.append(
        f"  stalls longer than {wires_s * 1e3:.2f} ms, the slack of a loop that did nothing but "
        f"wait for its wires ({report['tick_budget']['overlapped_s'] * 1e3:.2f} ms): "
        f"{floor['all']}, of which {floor['outside']} from outside the OS"
    )
    return lines
