"""`hil bench loop`'s speed figures: the bus alone (a read and a write of the held goal per
tick) runs the real bus, leaves torque off and the bus closed, and the speed report carries
every path with the host's CPU per tick and the factor it bounds. No timing is asserted."""

from __future__ import annotations

import pytest

from hil.bench.loop import LOOP_CONTROLLER, loop_experiment
from hil.bench.speed import BUS_ALONE_WARMUP_TICKS, PATHS, bench_speed, run_bus_alone, speed_text
from hil.config import load_config
from hil.wiring.in_process import in_process_bus


class _FailingWrite(Exception):
    pass


def test_the_bus_alone_reads_and_writes_each_tick_then_torque_off_and_closed() -> None:
    config = load_config()
    bus = in_process_bus(config, loop_experiment(config))
    record = run_bus_alone(config, bus, ticks=7)
    assert bus.reads == 1 + BUS_ALONE_WARMUP_TICKS + 7  # the first read, warm-up, measured
    assert bus.closed
    assert not any(device.torque_enabled for device in bus.testbed.robot.devices)
    assert record["simulated_s"] == pytest.approx(7 * config.loop.period_s)
    assert record["real_time_factor"] > 0 and record["host_cpu_s_per_tick"] > 0


def test_the_bus_alone_turns_torque_off_when_a_write_fails(monkeypatch) -> None:
    config = load_config()
    bus = in_process_bus(config, loop_experiment(config))
    calls: list[str] = []
    monkeypatch.setattr(bus, "disable", lambda: calls.append("disable"))

    def fail(_goal: object) -> None:
        raise _FailingWrite

    monkeypatch.setattr(bus, "write", fail)
    with pytest.raises(_FailingWrite):
        run_bus_alone(config, bus, ticks=3)
    assert calls == ["disable"] and bus.closed


@pytest.mark.timeout(120)
def test_the_speed_report_has_every_path_and_the_host_bound() -> None:
    config = load_config()
    speed = bench_speed(config, loop_experiment(config), LOOP_CONTROLLER, ticks=6, rounds=1)
    assert set(speed["real_time_factor"]) == set(PATHS)
    assert all(factor > 0 for factor in speed["real_time_factor"].values())
    assert all(ending in ("completed", "") for ending in speed["endings"].values())
    alone = speed["bus_alone"]
    assert alone["host_cpu_s_per_tick"] > 0
    assert alone["host_bound"] == pytest.approx(config.loop.period_s / alone["host_cpu_s_per_tick"])
    text = "\n".join(speed_text(speed))
    assert "the bus alone" in text and "at most, were the emulator and the loop free" in text
