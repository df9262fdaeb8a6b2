"""`hil bench bus` and `hil bench loop`: a smoke run of each bench (tiny cycle counts) through
`cmd_bench --json` (the wire-time formula is tested in tests/drivers/test_wire_time.py).

The smoke runs check the report's structure and that every figure is positive and finite; they
assert no timing (this is a shared, noisy 2-core VM). They run the real benches: emulator in a
child process (`hil emulate`), the unmodified dynamixel-sdk, python-can and canopen. The bench
widens the driver's reply timeout itself (`with_bench_reply_timeout`), so an emulator stall
cannot turn into a lost reply here.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest

from controller import CONTROLLER_NAMES
from drivers.dynamixel.wire_time import sync_cycle_wire_time_s
from hil.bench.bus import EMULATOR_LINES, JOINT_COUNTS, bus_report_text
from hil.bench.common import config_with_joints
from hil.bench.loop import loop_report_text
from hil.bench.pacing import pacing_report_text
from hil.cli import main
from hil.cli.bench import cmd_bench
from hil.cli.parser import build_parser
from hil.config import default_config_text, load_config

# The built-in testbed at another baud: the bench must take the configuration it is given.
CONFIG_AT_4_MBPS = default_config_text().replace("baudrate = 3000000", "baudrate = 4000000")


def _positive(value: Any) -> bool:
    return isinstance(value, int | float) and math.isfinite(value) and value > 0


def _one_json_line(capsys: pytest.CaptureFixture[str]) -> dict[str, Any]:
    out = capsys.readouterr().out.strip().splitlines()
    assert len(out) == 1, "--json prints exactly one line"
    return json.loads(out[0])


def test_config_with_joints_gives_distinct_addresses_and_no_force_sensor() -> None:
    config = config_with_joints(load_config(None), 12)
    assert [j.dynamixel_id for j in config.joints] == list(range(1, 13))
    assert [j.encoder_node_id for j in config.joints] == list(range(5, 17))
    assert len({j.name for j in config.joints}) == 12
    assert config.force_sensor.node_id == 0
    with pytest.raises(ValueError, match="n_joints"):
        config_with_joints(config, 0)


def test_bench_refuses_a_cycle_count_below_one(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "bus", "--cycles", "0"]) == 2
    assert "--cycles must be >= 1" in capsys.readouterr().err


@pytest.mark.timeout(120)
def test_bench_bus_smoke(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    config_path = tmp_path / "testbed-4mbps.toml"
    config_path.write_text(CONFIG_AT_4_MBPS)
    args = build_parser().parse_args(
        ["bench", "bus", "--json", "--cycles", "5", "--config", str(config_path)]
    )
    assert cmd_bench(args) == 0
    report = _one_json_line(capsys)
    assert report["bench"] == "bus" and report["cycles"] == 5
    assert report["baudrate"] == 4_000_000
    cases = report["cases"]
    assert [(c["emulator_line"], c["n_devices"]) for c in cases] == [
        (line, n) for line in EMULATOR_LINES for n in JOINT_COUNTS
    ]
    for case in cases:
        for loop in ("driver", "bare_sdk"):
            stats = case[loop]
            assert stats["cycles"] == 5
            assert all(_positive(stats[key]) for key in ("median_s", "p90_s", "max_s"))
            assert stats["median_s"] <= stats["p90_s"] <= stats["max_s"]
            assert 0 <= stats["failed_reads"] <= 5
        assert _positive(case["driver_over_bare"])
        assert case["driver_read_bytes_per_device"] == 15  # the indirect state block
        assert case["bare_read_bytes_per_device"] == 12  # 611 .. 622
        assert case["wire_time_driver_s"] > case["wire_time_bare_s"] > 0
        assert case["wire_time_driver_s"] == pytest.approx(
            sync_cycle_wire_time_s(case["n_devices"], 15, 4_000_000)
        )
        assert case["latency_timer_ms"] >= 10.0
        assert isinstance(case["failed_starts"], list)
    text = bus_report_text(report)
    assert "12  realtime" in text and "ratio" in text


@pytest.mark.timeout(120)
def test_bench_loop_smoke(capsys: pytest.CaptureFixture[str]) -> None:
    ticks = 10
    assert main(["bench", "loop", "--json", "--cycles", str(ticks)]) == 0
    report = _one_json_line(capsys)
    assert report["bench"] == "loop" and report["period_s"] == pytest.approx(0.005)
    controllers = report["controllers"]
    assert [(c["n_joints"], c["controller"]) for c in controllers] == [
        (n, name) for n in JOINT_COUNTS for name in CONTROLLER_NAMES
    ]
    for case in controllers:
        assert case["ticks"] == ticks
        assert all(_positive(case[key]) for key in ("median_s", "p99_s", "max_s", "build_s"))

    lockstep = report["lockstep_run"]
    assert lockstep["termination"] == "completed"
    stop_cycles = load_config(None).loop.stop_cycles
    assert lockstep["ticks"] == ticks + stop_cycles
    # the loop's span: from tick 1 to the last tick
    assert lockstep["simulated_s"] == pytest.approx((ticks + stop_cycles - 2) * 0.005)
    assert all(_positive(lockstep[key]) for key in ("loop_wall_s", "real_time_factor"))
    for part in ("bus_read", "compute_and_write"):
        assert _positive(lockstep["tick"][part]["median_s"])

    wall = report["wall_clock_run"]
    assert wall["rate_hz"] == 200.0
    assert wall["ticks"] >= 3
    assert wall["period"]["count"] >= 2 and _positive(wall["period"]["median_s"])
    lateness = wall["lateness"]
    assert all(math.isfinite(lateness[key]) for key in ("median_s", "p99_s", "max_s"))
    assert wall["slack"]["count"] >= 1
    assert isinstance(wall["overruns"], int) and isinstance(wall["skipped_ticks"], int)
    assert wall["overruns"] <= wall["ticks"]
    assert wall["latency_timer_ms"] >= 10.0
    stalls = report["cpu_stalls"]
    assert stalls["duration_s"] == pytest.approx(ticks * 0.005)
    assert len(stalls["lengths_s"]) == len(stalls["sources"]) == stalls["stalls"]["count"]
    text = loop_report_text(report)
    assert "real-time factor" in text and "lateness" in text and "never sleeps" in text


@pytest.mark.timeout(180)
def test_bench_pacing_alternates_the_two_ways_to_wait(capsys: pytest.CaptureFixture[str]) -> None:
    ticks = 10
    assert main(["bench", "pacing", "--json", "--cycles", str(ticks), "--runs", "2"]) == 0
    report = _one_json_line(capsys)
    assert report["bench"] == "pacing" and report["cases_ms"] == [0.3, 5.0]
    # A B A B: the configured sleep-then-spin, then never sleeping, in turn
    assert [(r["pair"], r["spin_before_tick_ms"]) for r in report["runs"]] == [
        (0, 0.3),
        (0, 5.0),
        (1, 0.3),
        (1, 5.0),
    ]
    for run in report["runs"]:
        assert run["ticks"] >= ticks and run["period"]["count"] >= 2
    a = sum(r["overruns"] for r in report["runs"] if r["spin_before_tick_ms"] == 0.3)
    assert report["overruns"][0] == a
    assert 0 <= report["pairs_fewer_never_sleeping"] <= 2
    assert "never sleep" in pacing_report_text(report)


def test_bench_refuses_a_pacing_run_count_below_one(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "pacing", "--runs", "0"]) == 2
    assert "--runs must be >= 1" in capsys.readouterr().err
