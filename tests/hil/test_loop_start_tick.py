"""The start-up tick on the wall clock: tick 0 runs the start gate and turns torque on (a
transaction per item and actuator: ~0.12 s on the humanoid's twelve), which no 5 ms deadline
can hold. The grid starts at its end, so a slow start-up is not a burst of missed deadlines
(before, every wall-clock humanoid run tripped the overrun watch at tick ~25)."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from hil.config import load_config
from hil.experiments import IMPACT
from hil.loop import RunRequest, WallClock, run_experiment
from hil.vocabulary import ControllerChoice
from hil.wiring.in_process import InProcessJointBus, in_process_bus

CONFIG = load_config()
START_UP_S = 0.15  # 30 periods: far beyond the overrun watch's 20 in a second


class _SlowStartBus(InProcessJointBus):
    def enable(self) -> None:
        time.sleep(START_UP_S)
        super().enable()


@pytest.mark.timing  # no skipped 5 ms tick: a wall-clock figure, measured with nothing beside it
def test_a_slow_start_up_is_no_overrun(tmp_path: Path) -> None:
    bus = in_process_bus(CONFIG, IMPACT)
    bus.__class__ = _SlowStartBus
    clock = WallClock(CONFIG.loop.period_s)
    request = RunRequest(IMPACT, ControllerChoice("pid", 1.0), tmp_path, duration_s=0.3)
    result = run_experiment(CONFIG, request, bus, clock, {"test": True})
    assert result.ok, result.ending
    assert clock.stats.skipped == 0
    assert result.safety_events == []
