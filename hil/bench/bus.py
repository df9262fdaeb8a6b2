"""`hil bench bus`: our driver's tick against a bare dynamixel-sdk loop, on the emulated chain.

For 1 and 12 actuators, on the emulator's instant line (replies as soon as the instruction is
parsed) and on its realtime line (replies at the wire model's due times):
- our driver's tick, `DynamixelChain.read_state()` + `write_goals()`, against a bare
  dynamixel-sdk GroupSyncRead(611, 12) + GroupSyncWrite(596, 4) loop, cycle by cycle,
  alternating which goes first (`drivers.dynamixel.bench_bus`); their ratio is the driver's
  overhead (it reads a 15-byte indirect state block with the hardware error and torque state,
  the bare loop the 12 bytes Present Position .. Present Current);
- the theoretical wire time of the same cycle at the configured baud
  (`drivers.dynamixel.wire_time`).
The emulator runs in a child process (`hil emulate`): the SDK busy-waits in its receive loop,
so an emulator in our own process would starve under the GIL. Figures print human-readable or
as one JSON object; nothing here asserts a timing.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from drivers.dynamixel import BusBenchResult, CycleStats, DynamixelChain, bench_bus
from drivers.dynamixel.wire_time import sync_cycle_wire_bytes, sync_cycle_wire_time_s
from hil.bench.common import (
    config_with_joints,
    failed_starts_text,
    machine,
    with_bench_reply_timeout,
    with_retries,
)
from hil.config import Config
from hil.vocabulary import EmulatorClock
from hil.wiring import Connection, bus_config
from hil.wiring.emulation import EmbeddedEmulator, emulator_spec

JOINT_COUNTS: tuple[int, ...] = (1, 12)  # the 1-DoF testbed and the humanoid's two legs
EMULATOR_LINES: tuple[str, ...] = ("instant", "realtime")
DEFAULT_BUS_CYCLES = 2000
BUS_WARMUP_CYCLES = 50


def _cycle_stats_dict(stats: CycleStats) -> dict[str, Any]:
    return {
        "median_s": stats.median_s,
        "p90_s": stats.p90_s,
        "max_s": stats.max_s,
        "failed_reads": stats.failures,
        "cycles": stats.cycles,
    }


def _emulator_clock(line: str) -> EmulatorClock:
    """The emulator clock behind each line mode: lock-step answers at once, realtime on time."""
    return EmulatorClock.LOCKSTEP if line == "instant" else EmulatorClock.REALTIME


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
        connection = Connection.from_endpoints(emulator.endpoints, config)
        chain = DynamixelChain(bus_config(config, connection).chains[0])
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
            case, failures = with_retries(
                what,
                functools.partial(bench_bus_case, config, n_devices, line, cycles, warmup),
                say,
            )
            cases.append(dataclasses.replace(case, failed_starts=tuple(failures)))
    return {
        "bench": "bus",
        "machine": machine(),
        "config": config.source,
        "baudrate": config.dynamixel[0].baudrate,
        "return_delay_time_us": config.dynamixel[0].return_delay_time_us,
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
        lines += failed_starts_text(what, case["failed_starts"])
    return "\n".join(lines)


def _first(report: dict[str, Any], key: str) -> Any:
    return report["cases"][0][key] if report["cases"] else "?"


def _ms3(stats: dict[str, Any]) -> str:
    return (
        f"{stats['median_s'] * 1e3:.3f} / {stats['p90_s'] * 1e3:.3f} / {stats['max_s'] * 1e3:.3f}"
    )
