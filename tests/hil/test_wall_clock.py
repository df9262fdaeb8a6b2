"""The wall clock's pacing on a fake time: absolute deadlines, sleep then spin the configured
last stretch (or never sleep), overruns counted and missed grid ticks skipped."""

from __future__ import annotations

import pytest

import hil.loop.clock as clock_module
from hil.config import default_config_text, parse_config
from hil.loop.clock import WallClock
from hil.session import Session, Setup

PERIOD_S = 0.005
READ_COST_S = 1e-6  # every reading of the fake clock advances it this much


class FakeTime:
    def __init__(self) -> None:
        self.now = 0.0
        self.sleeps: list[float] = []

    def perf_counter(self) -> float:
        self.now += READ_COST_S
        return self.now

    def sleep(self, duration_s: float) -> None:
        self.sleeps.append(duration_s)
        self.now += duration_s


@pytest.fixture
def fake_time(monkeypatch: pytest.MonkeyPatch) -> FakeTime:
    fake = FakeTime()
    monkeypatch.setattr(clock_module, "time", fake)
    return fake


def test_sleeps_to_the_spin_stretch_then_spins_to_the_deadline(fake_time: FakeTime) -> None:
    clock = WallClock(PERIOD_S, spin_s=0.0003)
    clock.next_tick()
    fake_time.now += 0.001  # the cycle's work
    tick = clock.next_tick()
    assert fake_time.sleeps == [pytest.approx(PERIOD_S - 0.001 - 0.0003, abs=1e-5)]
    assert tick.index == 1 and tick.skipped == 0
    assert tick.slack_s == pytest.approx(PERIOD_S - 0.001, abs=1e-5)
    assert fake_time.now == pytest.approx(PERIOD_S, abs=1e-5)  # started at its grid time


def test_a_spin_stretch_of_a_period_or_more_never_sleeps(fake_time: FakeTime) -> None:
    clock = WallClock(PERIOD_S, spin_s=PERIOD_S)
    clock.next_tick()
    for k in range(1, 4):
        fake_time.now += 0.001
        tick = clock.next_tick()
        assert tick.index == k
        assert fake_time.now == pytest.approx(k * PERIOD_S, abs=1e-5)
    assert fake_time.sleeps == []


def test_an_overrun_is_counted_and_whole_missed_periods_skipped(fake_time: FakeTime) -> None:
    clock = WallClock(PERIOD_S)
    clock.next_tick()
    fake_time.now += 0.012  # ends 7 ms after tick 1's start: tick 1 missed, tick 2 late
    tick = clock.next_tick()
    assert (tick.index, tick.skipped) == (2, 1)
    assert tick.slack_s == pytest.approx(-0.007, abs=1e-5)
    assert clock.stats.overruns == 1 and clock.stats.skipped == 1
    assert fake_time.sleeps == []  # run at once
    fake_time.now += 0.001
    assert clock.next_tick().index == 3
    assert fake_time.now == pytest.approx(3 * PERIOD_S, abs=1e-5)  # back on the grid


def test_the_start_up_tick_is_not_judged_against_a_deadline(fake_time: FakeTime) -> None:
    """Tick 0 turns torque on (~0.12 s on the humanoid): the grid starts at its end, so the
    first control tick is due a period later and nothing counts as missed."""
    clock = WallClock(PERIOD_S)
    clock.next_tick()
    fake_time.now += 0.120  # the start gate and torque on
    clock.start_grid()
    anchored = fake_time.now
    tick = clock.next_tick()
    assert (tick.index, tick.skipped) == (1, 0)
    assert tick.slack_s == pytest.approx(PERIOD_S, abs=1e-5)
    assert clock.stats.overruns == 0
    assert fake_time.now == pytest.approx(anchored + PERIOD_S, abs=1e-5)
    assert clock.grid_origin_s == pytest.approx(anchored, abs=1e-5)
    fake_time.now += 0.001
    assert clock.next_tick().index == 2
    assert fake_time.now == pytest.approx(anchored + 2 * PERIOD_S, abs=1e-5)


def test_without_the_re_anchoring_the_start_up_tick_is_an_overrun(fake_time: FakeTime) -> None:
    clock = WallClock(PERIOD_S)
    clock.next_tick()
    fake_time.now += 0.120
    tick = clock.next_tick()
    assert tick.skipped == 23 and clock.stats.overruns == 1


def test_a_negative_spin_stretch_is_refused() -> None:
    with pytest.raises(ValueError, match="spin_s"):
        WallClock(PERIOD_S, spin_s=-0.001)


def test_a_realtime_session_paces_with_the_configured_spin_stretch() -> None:
    text = default_config_text().replace("spin_before_tick_ms = 0.3", "spin_before_tick_ms = 5.0")
    config = parse_config(text, source="spin.toml")
    clock = Session(config, Setup.EMBEDDED, realtime=True).clock()
    assert isinstance(clock, WallClock) and clock.spin_s == pytest.approx(0.005)
    default = Session(parse_config(default_config_text()), Setup.EMBEDDED, realtime=True).clock()
    assert isinstance(default, WallClock) and default.spin_s == pytest.approx(0.0003)
