"""`hil bench bus` and `hil bench loop`: what the bus and the 200 Hz loop cost on this machine.

Both run against the emulated testbed in a child process (`hil emulate`, started through
`EmbeddedEmulator`: the SDK busy-waits in its receive loop, so an emulator in our own process
would starve under the GIL). This machine is shared and noisy, so whatever is compared is
measured side by side in one run, interleaved, never in two separate runs.

bench bus, for 1 and 12 actuators, on the emulator's instant line (replies as soon as the
instruction is parsed) and on its realtime line (replies at the wire model's due times):
- our driver's tick, `DynamixelChain.read_state()` + `write_goals()`, against a bare
  dynamixel-sdk GroupSyncRead(611, 12) + GroupSyncWrite(596, 4) loop, cycle by cycle,
  alternating which goes first (`drivers.dynamixel.bench_bus`); their ratio is the driver's
  overhead (it reads a 15-byte indirect state block with the hardware error and torque state,
  the bare loop the 12 bytes Present Position .. Present Current);
- the theoretical wire time of the same cycle at the configured baud (`sync_cycle_wire_time_s`).

bench loop:
- controller compute per tick (`step` + `notify_applied`) of all four controllers for 1 and
  12 joints, interleaved tick by tick;
- the real-time factor of a lock-step run of the impact experiment with gc+lqr+dob through the
  emulated buses (`hil.runner.run_experiment`, the loop `hil run` uses): simulated s / wall s;
- the 200 Hz wall-clock loop (`hil.clock.WallClock`) running the same experiment against the
  emulator in realtime mode: measured period, lateness of each tick's start behind its grid
  time, slack, overruns and skipped ticks.

Against the emulator the driver's reply timeout is widened to a latency term of at least
10 ms (`with_bench_reply_timeout`: a stall of the emulator process shows in the maxima instead
of losing a reply), and a measurement that fails to start is retried up to 3 times, the
failures reported with the figures (`_with_retries`).

Figures print human-readable, or as one JSON object (`--json`; seconds, SI). Nothing here
asserts a timing: the figures are for the reader.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import math
import os
import platform
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from controller import CONTROLLER_NAMES, JointController
from drivers.dynamixel import BusBenchResult, CycleStats, DynamixelChain, bench_bus
from drivers.joint_bus import BusError
from hil.clock import LockstepClock, LoopClock, Tick, WallClock
from hil.config import Config, load_config
from hil.emulation import EmbeddedEmulator, EmulatorStartError, emulator_spec
from hil.experiments import IMPACT, Experiment
from hil.hardware import Connection, bus_config, make_bus
from hil.runner import RunRequest, RunResult, build_controller, run_experiment

EXIT_OK, EXIT_FAILED, EXIT_USAGE = 0, 1, 2

JOINT_COUNTS: tuple[int, ...] = (1, 12)  # the 1-DoF testbed and the humanoid's two legs
EMULATOR_LINES: tuple[str, ...] = ("instant", "realtime")
DEFAULT_BUS_CYCLES = 2000
BUS_WARMUP_CYCLES = 50
DEFAULT_LOOP_TICKS = 1000  # 5 s at 200 Hz: the whole impact experiment
CONTROLLER_WARMUP_TICKS = 20
LOOP_CONTROLLER = "gc+lqr+dob"
FIRST_ENCODER_NODE_ID = 5  # as `sim_backend.server.joint_specs_from_ids`
MAX_ATTEMPTS = 3  # per measurement, when it fails to start (see `_with_retries`)
# The reply timeout's latency term for the benches (the configured one if longer): see
# `with_bench_reply_timeout`.
BENCH_MIN_LATENCY_TIMER_MS = 10.0
MIN_RUN_TICKS = 3  # a run that made fewer ticks did not get going

T = TypeVar("T")

# Protocol 2.0 packet sizes (ROBOTIS e-Manual, Protocol 2.0, "Instruction Packet" / "Status
# Packet"): header FF FF FD 00 (4) + ID (1) + LENGTH (2) + INSTRUCTION (1) + CRC (2) = 10 bytes
# around the parameters; a status packet adds the ERR byte.
PACKET_OVERHEAD_BYTES = 10
SYNC_PARAMS_HEADER_BYTES = 4  # start address (2) + data length (2)
STATUS_OVERHEAD_BYTES = PACKET_OVERHEAD_BYTES + 1
BITS_PER_BYTE_ON_WIRE = 10  # 8N1: start + 8 data + stop
GOAL_POSITION_BYTES = 4


class BenchError(RuntimeError):
    """A bench could not complete (the message says why)."""


class _StartFailed(RuntimeError):
    """A measurement did not get going (emulator start, bus open, the run's first ticks)."""


def _with_retries(
    what: str, run: Callable[[], T], say: Callable[[str], None]
) -> tuple[T, list[str]]:
    """run() up to MAX_ATTEMPTS times while it fails to start; returns its result and the
    failures before it, which are reported with the figures.

    Why: on this shared 2-core VM a freshly started emulator now and then answers one of its
    first requests 3-7 ms late (measured), beyond the ~4 ms reply timeout that the configured
    1 ms latency timer gives on the realtime line (2 x 1 ms + 2 ms + wire time).
    """
    failures: list[str] = []
    for attempt in range(1, MAX_ATTEMPTS + 1):
        try:
            return run(), failures
        except (_StartFailed, BusError, EmulatorStartError) as exc:
            failures.append(f"{type(exc).__name__}: {exc}")
            say(f"  {what}: attempt {attempt} of {MAX_ATTEMPTS} failed to start: {exc}")
    raise BenchError(f"{what}: {MAX_ATTEMPTS} attempts failed; the last: {failures[-1]}")


# --------------------------------------------------------------------------- the wire model


def sync_cycle_wire_bytes(
    n_devices: int, read_bytes: int, write_bytes: int = GOAL_POSITION_BYTES
) -> int:
    """Bytes on the RS-485 line for one SYNC_READ + its replies + one SYNC_WRITE.

    SYNC_READ (0x82): 10 + 4 + N (the ID list) = 14 + N;
    N status packets of 11 + L bytes each (L = `read_bytes`);
    SYNC_WRITE (0x83): 10 + 4 + N (1 + W) (ID + data per device) = 14 + 5N for W = 4.
    Byte stuffing (an extra 0xFD after any FF FF FD in a packet) is ignored.
    Worked example: 6 x H54, L = 12 (Present Position .. Present Current): 202 bytes.
    """
    if n_devices < 1 or read_bytes < 1 or write_bytes < 1:
        raise ValueError(
            f"need n_devices, read_bytes and write_bytes >= 1, got {n_devices}, {read_bytes}, "
            f"{write_bytes}"
        )
    sync_read = PACKET_OVERHEAD_BYTES + SYNC_PARAMS_HEADER_BYTES + n_devices
    replies = n_devices * (STATUS_OVERHEAD_BYTES + read_bytes)
    sync_write = PACKET_OVERHEAD_BYTES + SYNC_PARAMS_HEADER_BYTES + n_devices * (1 + write_bytes)
    return sync_read + replies + sync_write


def sync_cycle_wire_time_s(
    n_devices: int,
    read_bytes: int,
    baudrate_bps: int,
    return_delay_time_us: float = 0.0,
    write_bytes: int = GOAL_POSITION_BYTES,
) -> float:
    """The cycle's time on the wire: bytes x 10 bits / baud, plus N x Return Delay Time.

    Each device waits its Return Delay Time (item 9, 2 us units) before answering, one after
    the other (e-Manual H54; DynamixelSDK issue #302: 6 x 500 us explained a > 4 ms sync read).
    USB latency and OS scheduling come on top on real hardware.
    """
    if baudrate_bps <= 0 or return_delay_time_us < 0:
        raise ValueError(
            f"need baudrate_bps > 0 and return_delay_time_us >= 0, got {baudrate_bps}, "
            f"{return_delay_time_us}"
        )
    n_bytes = sync_cycle_wire_bytes(n_devices, read_bytes, write_bytes)
    return n_bytes * BITS_PER_BYTE_ON_WIRE / baudrate_bps + n_devices * return_delay_time_us * 1e-6


# ------------------------------------------------------------------------------ statistics


@dataclass(frozen=True)
class Distribution:
    """Summary of a sample of durations or times [s]."""

    count: int
    min_s: float
    median_s: float
    p99_s: float
    max_s: float

    @classmethod
    def of(cls, samples_s: np.ndarray) -> Distribution:
        samples = np.asarray(samples_s, dtype=float)
        samples = samples[np.isfinite(samples)]
        if samples.size == 0:
            return cls(0, math.nan, math.nan, math.nan, math.nan)
        return cls(
            count=int(samples.size),
            min_s=float(samples.min()),
            median_s=float(np.median(samples)),
            p99_s=float(np.percentile(samples, 99)),
            max_s=float(samples.max()),
        )

    def text(self, scale: float = 1e3) -> str:
        return f"{self.median_s * scale:.3f} / {self.p99_s * scale:.3f} / {self.max_s * scale:.3f}"


def _cycle_stats_dict(stats: CycleStats) -> dict[str, Any]:
    return {
        "median_s": stats.median_s,
        "p90_s": stats.p90_s,
        "max_s": stats.max_s,
        "failed_reads": stats.failures,
        "cycles": stats.cycles,
    }


# ------------------------------------------------------------------------ test configurations


def config_with_joints(base: Config, n_joints: int) -> Config:
    """`base` with `n_joints` copies of its first joint (Dynamixel IDs 1..n, encoder nodes 5..).

    The force sensor is left out, so its node ID cannot clash with an encoder's.
    """
    if not 1 <= n_joints <= 100:
        raise ValueError(f"n_joints must be in 1..100, got {n_joints}")
    template = base.joints[0]
    joints = tuple(
        dataclasses.replace(
            template,
            name=f"joint{index + 1}" if n_joints > 1 else template.name,
            dynamixel_id=index + 1,
            encoder_node_id=FIRST_ENCODER_NODE_ID + index,
        )
        for index in range(n_joints)
    )
    return base.with_overrides(
        joints=joints, force_sensor=dataclasses.replace(base.force_sensor, node_id=0)
    )


def with_bench_reply_timeout(config: Config) -> Config:
    """`config` with a Dynamixel latency timer of at least BENCH_MIN_LATENCY_TIMER_MS.

    The latency term sets the driver's reply timeout (2 x latency + 2 ms + wire time); it
    changes no figure while replies arrive. On this shared 2-core VM the emulator process now
    and then answers 3-7 ms late (measured; most often just after it started), past the ~4 ms
    timeout of the built-in 1 ms: with it a bench would lose that reply (a failed read; in a
    run, a safety stop) instead of showing the stall in its maxima. Lock-step connections
    already widen it (`hil.hardware.LOCKSTEP_LATENCY_TIMER_MS`).
    """
    dynamixel = config.dynamixel
    if dynamixel.latency_timer_ms >= BENCH_MIN_LATENCY_TIMER_MS:
        return config
    return config.with_overrides(
        dynamixel=dataclasses.replace(dynamixel, latency_timer_ms=BENCH_MIN_LATENCY_TIMER_MS)
    )


def _emulator_clock(line: str) -> str:
    """The emulator clock behind each line mode: lock-step answers at once, realtime on time."""
    return "lockstep" if line == "instant" else "realtime"


# ------------------------------------------------------------------------------- bench bus


@dataclass(frozen=True)
class BusCase:
    """One (number of devices, emulator line) measurement of `hil bench bus`."""

    n_devices: int
    line: str
    baudrate: int
    return_delay_time_us: int
    driver_read_bytes: int
    bare_read_bytes: int
    latency_timer_ms: float  # the reply timeout's latency term the driver used
    result: BusBenchResult
    failed_starts: tuple[str, ...] = ()

    @property
    def ratio(self) -> float:
        """Driver median / bare median: the driver's overhead factor."""
        return self.result.chain.median_s / self.result.bare.median_s

    def wire_time_s(self, read_bytes: int) -> float:
        return sync_cycle_wire_time_s(
            self.n_devices, read_bytes, self.baudrate, self.return_delay_time_us
        )

    def as_dict(self) -> dict[str, Any]:
        return {
            "n_devices": self.n_devices,
            "emulator_line": self.line,
            "driver": _cycle_stats_dict(self.result.chain),
            "bare_sdk": _cycle_stats_dict(self.result.bare),
            "driver_over_bare": self.ratio,
            "driver_minus_bare_s": self.result.chain.median_s - self.result.bare.median_s,
            "driver_read_bytes_per_device": self.driver_read_bytes,
            "bare_read_bytes_per_device": self.bare_read_bytes,
            "wire_bytes_driver": sync_cycle_wire_bytes(self.n_devices, self.driver_read_bytes),
            "wire_bytes_bare": sync_cycle_wire_bytes(self.n_devices, self.bare_read_bytes),
            "wire_time_driver_s": self.wire_time_s(self.driver_read_bytes),
            "wire_time_bare_s": self.wire_time_s(self.bare_read_bytes),
            "latency_timer_ms": self.latency_timer_ms,
            "failed_starts": list(self.failed_starts),
        }


def bench_bus_case(
    base: Config, n_devices: int, line: str, cycles: int, warmup: int = BUS_WARMUP_CYCLES
) -> BusCase:
    """Start an emulator with `n_devices` H54s, open our driver on it, run `bench_bus`.

    Torque is turned on (goal = present position) so the emulated joints hold still on the
    realtime line, and off again at the end.
    """
    if line not in EMULATOR_LINES:
        raise ValueError(f"line must be one of {EMULATOR_LINES}, got {line!r}")
    config = config_with_joints(base, n_devices)
    spec = emulator_spec(config, clock=_emulator_clock(line))
    with EmbeddedEmulator(spec) as emulator:
        connection = Connection.from_endpoints(emulator.endpoints)
        chain = DynamixelChain(bus_config(config, connection).dynamixel)
        try:
            chain.open()
            chain.enable()
            result = bench_bus(chain, cycles=cycles, warmup=warmup)
            chain.disable()
        finally:
            chain.close()
        position = chain.spec.item("Present Position")
        current = chain.spec.item("Present Current")
        return BusCase(
            n_devices=n_devices,
            line=line,
            baudrate=chain.config.baudrate,
            return_delay_time_us=chain.config.return_delay_time_us,
            driver_read_bytes=chain.layout.size,
            bare_read_bytes=current.address + current.size - position.address,
            latency_timer_ms=chain.config.latency_timer_ms,
            result=result,
        )


def run_bench_bus(
    config: Config,
    cycles: int = DEFAULT_BUS_CYCLES,
    *,
    joint_counts: Sequence[int] = JOINT_COUNTS,
    lines: Sequence[str] = EMULATOR_LINES,
    warmup: int = BUS_WARMUP_CYCLES,
    say: Callable[[str], None] = lambda _text: None,
) -> dict[str, Any]:
    """Every (line, device count) case; returns the JSON-ready report."""
    config = with_bench_reply_timeout(config)
    cases = []
    for line in lines:
        for n_devices in joint_counts:
            what = f"bench bus: {n_devices} device(s), {line} emulator line"
            say(f"{what}, {cycles} cycles ...")
            case, failures = _with_retries(
                what,
                functools.partial(bench_bus_case, config, n_devices, line, cycles, warmup),
                say,
            )
            cases.append(dataclasses.replace(case, failed_starts=tuple(failures)))
    return {
        "bench": "bus",
        "machine": _machine(),
        "config": config.source,
        "baudrate": config.dynamixel.baudrate,
        "return_delay_time_us": config.dynamixel.return_delay_time_us,
        "cycles": cycles,
        "warmup_cycles": warmup,
        "method": (
            "per cycle, interleaved (alternating which goes first): driver = "
            "DynamixelChain.read_state() + write_goals(); bare_sdk = GroupSyncRead(611, 12)."
            "txRxPacket() + getData x3 per ID, then GroupSyncWrite(596, 4).txPacket(); "
            "emulator in a separate process (hil emulate); wire time = bytes x 10 / baud + "
            "N x Return Delay Time"
        ),
        "cases": [case.as_dict() for case in cases],
    }


def bus_report_text(report: dict[str, Any]) -> str:
    lines = [
        "hil bench bus: our driver's tick against a bare dynamixel-sdk loop, interleaved, on the "
        "emulated H54 chain (separate process)",
        f"  {report['baudrate']} bps, Return Delay Time {report['return_delay_time_us']} us, "
        f"{report['cycles']} cycles per case after {report['warmup_cycles']} warm-up",
        "  driver = DynamixelChain.read_state() + write_goals() (indirect state block, "
        f"{_first(report, 'driver_read_bytes_per_device')} bytes per ID); bare = GroupSyncRead"
        f"(611, {_first(report, 'bare_read_bytes_per_device')}) + GroupSyncWrite(596, 4)",
        "  reply timeout 2 x latency + 2 ms + wire time, latency "
        + ", ".join(
            sorted(
                {f"{c['latency_timer_ms']:g} ms ({c['emulator_line']})" for c in report["cases"]}
            )
        ),
        "",
        f"  {'IDs':>3}  {'line':<8}  {'driver median/p90/max [ms]':<27}  "
        f"{'bare median/p90/max [ms]':<25}  {'ratio':>5}  {'wire drv/bare [ms]':<18}  failed",
    ]
    for case in report["cases"]:
        driver, bare = case["driver"], case["bare_sdk"]
        lines.append(
            f"  {case['n_devices']:>3}  {case['emulator_line']:<8}  "
            f"{_ms3(driver):<27}  {_ms3(bare):<25}  {case['driver_over_bare']:>5.2f}  "
            f"{case['wire_time_driver_s'] * 1e3:.3f} / {case['wire_time_bare_s'] * 1e3:.3f}"
            f"{'':<4}  {driver['failed_reads']}/{bare['failed_reads']}"
        )
    lines.append(
        "  (ratio = driver median / bare median; wire = theoretical line time of the cycle, "
        "failed = invalid reads driver/bare; the instant line answers at once, the realtime "
        "line after the wire time)"
    )
    for case in report["cases"]:
        what = f"{case['n_devices']} IDs, {case['emulator_line']} line"
        lines += _failed_starts_text(what, case["failed_starts"])
    return "\n".join(lines)


def _first(report: dict[str, Any], key: str) -> Any:
    return report["cases"][0][key] if report["cases"] else "?"


def _failed_starts_text(what: str, failures: Sequence[str]) -> list[str]:
    return [f"  note: {what}: a start failed and was retried: {failure}" for failure in failures]


def _termination_text(run: dict[str, Any]) -> list[str]:
    lines = _failed_starts_text(f"{run['experiment']} run", run["failed_starts"])
    if run["termination"] != "completed":
        lines.append(f"  note: the run ended early: {run['termination']}")
    return lines


def _ms3(stats: dict[str, Any]) -> str:
    return (
        f"{stats['median_s'] * 1e3:.3f} / {stats['p90_s'] * 1e3:.3f} / {stats['max_s'] * 1e3:.3f}"
    )


# ------------------------------------------------------------------- bench loop: controllers


def _controller_inputs(
    n_joints: int, ticks: int, period_s: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Plausible motor / link / reference angles [rad] (ticks x n): a slow swing, a small
    deflection. The controllers' cost does not depend on the values; they just stay finite."""
    time_s = np.arange(ticks)[:, None] * period_s
    phase = np.arange(n_joints)[None, :] * 0.3
    reference = 0.2 * np.sin(2 * np.pi * 0.5 * time_s + phase)
    link = reference + 0.01 * np.sin(2 * np.pi * 3.0 * time_s + phase)
    motor = link + 0.005 * np.cos(2 * np.pi * 3.0 * time_s + phase)
    return motor, link, reference


def bench_controllers(
    base: Config,
    ticks: int,
    *,
    joint_counts: Sequence[int] = JOINT_COUNTS,
    names: Sequence[str] = CONTROLLER_NAMES,
    warmup: int = CONTROLLER_WARMUP_TICKS,
) -> list[dict[str, Any]]:
    """Time step + notify_applied of every (n joints, controller), interleaved tick by tick.

    Each tick runs every case once, the order rotated by one each tick, so a burst of machine
    load falls on all of them alike. build_s is make_controller's time (LQR design included).
    """
    period_s = base.loop.period_s
    kdist = base.controller.kdist
    cases: list[tuple[int, str]] = [(n, name) for n in joint_counts for name in names]
    controllers: list[JointController] = []
    build_s: list[float] = []
    inputs: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
    total = warmup + ticks
    for n_joints, name in cases:
        config = config_with_joints(base, n_joints)
        started = time.perf_counter()
        controller = build_controller(config, name, kdist, period_s)
        build_s.append(time.perf_counter() - started)
        if n_joints not in inputs:
            inputs[n_joints] = _controller_inputs(n_joints, total, period_s)
        motor, link, reference = inputs[n_joints]
        controller.reset(motor[0], link[0], reference[0])
        controllers.append(controller)
    durations_s = np.empty((len(cases), total))
    order = list(range(len(cases)))
    clock = time.perf_counter
    for k in range(total):
        shift = k % len(order)
        for index in order[shift:] + order[:shift]:
            controller = controllers[index]
            motor, link, reference = inputs[cases[index][0]]
            started = clock()
            goal = controller.step(motor[k], link[k], reference[k])
            controller.notify_applied(goal)
            durations_s[index, k] = clock() - started
    results = []
    for index, (n_joints, name) in enumerate(cases):
        stats = Distribution.of(durations_s[index, warmup:])
        results.append(
            {
                "n_joints": n_joints,
                "controller": name,
                "ticks": stats.count,
                "median_s": stats.median_s,
                "p99_s": stats.p99_s,
                "max_s": stats.max_s,
                "build_s": build_s[index],
            }
        )
    return results


# ------------------------------------------------------------ bench loop: the run's own loop


class RecordingClock(LoopClock):
    """Wraps the loop's clock and records, per tick, when it started (perf_counter) and what
    the clock said about it; preallocated, so recording costs no allocation in the loop.

    grid_origin_s: perf_counter just before the first tick was asked for. The wall clock
    anchors its grid when that call arrives, so `started_s[k] - (grid_origin_s + index * period)`
    is the tick's lateness, overstated (never understated) by the few microseconds a
    `next_tick()` call takes to return.
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

    @property
    def deterministic(self) -> bool:
        return self.inner.deterministic

    def next_tick(self) -> Tick:
        if self.count == 0:
            self.grid_origin_s = time.perf_counter()
        tick = self.inner.next_tick()
        started = time.perf_counter()
        k = self.count
        if k < self.started_s.size:
            self.started_s[k] = started
            self.grid_index[k] = tick.index
            self.measured_period_s[k] = tick.measured_period_s
            self.slack_s[k] = tick.slack_s
            self.skipped[k] = tick.skipped
        self.count += 1
        return tick

    def recorded(self) -> slice:
        return slice(0, min(self.count, self.started_s.size))


@dataclass(frozen=True)
class _RunRecord:
    clock: RecordingClock
    result: RunResult
    timing_csv: Path  # the runner's per-tick timing
    latency_timer_ms: float  # the Dynamixel reply timeout's latency term the run used


def _run_impact(base: Config, ticks: int, realtime: bool, out_dir: Path) -> _RunRecord:
    """The impact experiment with gc+lqr+dob for `ticks` ticks, the way `hil run` runs it."""
    experiment: Experiment = IMPACT
    period_s = base.loop.period_s
    spec = emulator_spec(base, experiment=experiment, clock="realtime" if realtime else "lockstep")
    inner: LoopClock = WallClock(period_s) if realtime else LockstepClock(period_s)
    capacity = ticks + 2 * base.loop.stop_cycles + 1
    clock = RecordingClock(inner, capacity)
    request = RunRequest(
        experiment=experiment,
        controller=LOOP_CONTROLLER,
        kdist=base.controller.kdist,
        out_dir=out_dir,
        duration_s=ticks * period_s,
        progress=False,
    )
    with EmbeddedEmulator(spec) as emulator:
        connection = Connection.from_endpoints(emulator.endpoints)
        bus_clock = inner.now if isinstance(inner, LockstepClock) else time.monotonic
        bus = make_bus(base, connection, clock=bus_clock)
        meta = {"bench": "hil bench loop", "clock": "wall" if realtime else "lockstep"}
        result = run_experiment(base, request, bus, clock, meta)
    if result.ticks < MIN_RUN_TICKS:
        raise _StartFailed(f"the run ended after {result.ticks} tick(s): {result.termination}")
    latency_ms = bus.config.dynamixel.latency_timer_ms
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
    record, failures = _with_retries(
        "lock-step run", lambda: _run_impact(base, ticks, realtime=False, out_dir=out_dir), say
    )
    clock, result = record.clock, record.result
    started = clock.started_s[clock.recorded()]
    simulated_s = (started.size - 2) * clock.period_s
    wall_s = float(started[-1] - started[1])
    return {
        "experiment": IMPACT.name,
        "controller": LOOP_CONTROLLER,
        "kdist": base.controller.kdist,
        "ticks": int(result.ticks),
        "termination": result.termination,
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
    record, failures = _with_retries(
        "wall-clock run", lambda: _run_impact(base, ticks, realtime=True, out_dir=out_dir), say
    )
    clock, result = record.clock, record.result
    recorded = clock.recorded()
    started = clock.started_s[recorded]
    grid = clock.grid_index[recorded]
    lateness = started - (clock.grid_origin_s + grid * clock.period_s)
    inner = clock.inner
    assert isinstance(inner, WallClock)
    return {
        "experiment": IMPACT.name,
        "controller": LOOP_CONTROLLER,
        "rate_hz": base.loop.rate_hz,
        "ticks": int(result.ticks),
        "termination": result.termination,
        "failed_starts": failures,
        "period": dataclasses.asdict(Distribution.of(clock.measured_period_s[recorded][1:])),
        "lateness": dataclasses.asdict(Distribution.of(lateness[1:])),
        "slack": dataclasses.asdict(Distribution.of(clock.slack_s[recorded][1:])),
        "overruns": inner.stats.overruns,
        "skipped_ticks": inner.stats.skipped,
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
    config = with_bench_reply_timeout(config)
    say(
        f"bench loop: {len(CONTROLLER_NAMES)} controllers x {len(joint_counts)} sizes, {ticks} "
        "ticks interleaved ..."
    )
    controllers = bench_controllers(config, ticks, joint_counts=joint_counts)
    with tempfile.TemporaryDirectory(prefix="hil-bench-") as tmp:
        say(f"bench loop: lock-step {IMPACT.name} run with {LOOP_CONTROLLER}, {ticks} ticks ...")
        lockstep = bench_lockstep_run(config, ticks, Path(tmp) / "lockstep", say)
        say(
            f"bench loop: wall-clock {config.loop.rate_hz:g} Hz {IMPACT.name} run against the "
            f"realtime emulator, {ticks} ticks ({ticks * config.loop.period_s:g} s) ..."
        )
        wall = bench_wall_clock(config, ticks, Path(tmp) / "wall", say)
    return {
        "bench": "loop",
        "machine": _machine(),
        "config": config.source,
        "period_s": config.loop.period_s,
        "controllers": controllers,
        "lockstep_run": lockstep,
        "wall_clock_run": wall,
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
        *_termination_text(lock),
    ]
    wall = report["wall_clock_run"]
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
        f"  overruns {wall['overruns']}, skipped ticks {wall['skipped_ticks']}",
        *_termination_text(wall),
    ]
    return "\n".join(lines)


# --------------------------------------------------------------------------------- command


def _without_nan(value: Any) -> Any:
    """NaN/inf (an empty statistic) -> None, so that --json prints strict JSON."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {key: _without_nan(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [_without_nan(item) for item in value]
    return value


def _machine() -> dict[str, Any]:
    load = os.getloadavg() if hasattr(os, "getloadavg") else (math.nan,) * 3
    return {
        "python": platform.python_version(),
        "platform": platform.platform(),
        "cpu_count": os.cpu_count(),
        "load_average_1min": load[0],
    }


def cmd_bench(args: argparse.Namespace) -> int:
    """`hil bench bus|loop [--json] [--cycles N]`."""
    cycles = args.cycles
    if cycles is not None and cycles < 1:
        print(f"hil bench: --cycles must be >= 1, got {cycles}", file=sys.stderr)
        return EXIT_USAGE
    # `hil bench` has no --config yet: the built-in testbed, unless the caller passes one
    config = load_config(getattr(args, "config", None))

    def say(text: str) -> None:
        if not args.json:
            print(text, file=sys.stderr, flush=True)

    try:
        if args.what == "bus":
            report = run_bench_bus(config, cycles or DEFAULT_BUS_CYCLES, say=say)
            text = bus_report_text(report)
        else:
            report = run_bench_loop(config, cycles or DEFAULT_LOOP_TICKS, say=say)
            text = loop_report_text(report)
    except (EmulatorStartError, BenchError, BusError, OSError) as exc:
        print(f"hil bench {args.what}: {exc}", file=sys.stderr)
        return EXIT_FAILED
    print(json.dumps(_without_nan(report), allow_nan=False) if args.json else text)
    return EXIT_OK
