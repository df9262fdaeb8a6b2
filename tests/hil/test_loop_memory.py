"""A run's memory does not grow with its planned duration: the loop computes its reference a
bounded number of ticks ahead, not for the whole run at its first tick (a `--duration 1e9`
once turned torque on and then died of a MemoryError). And the reference it uses is the
experiment's, tick by tick, also past that horizon and after skipped ticks."""

from __future__ import annotations

import tracemalloc
from pathlib import Path

import numpy as np
import pytest

import hil.loop.experiment_feed
from hil.config import load_config
from hil.experiments import CONTACT, IMPACT
from hil.loop import LockstepClock, RunRequest, StopFlag, run_experiment
from hil.vocabulary import ControllerChoice
from hil.wiring.in_process import in_process_bus
from tests.support.rig import run_in_process


def _stop_after(stop: StopFlag, seconds: float):
    def progress(time_s: float, _total_s: float) -> None:
        if time_s >= seconds:
            stop.reason = "test"

    return progress


@pytest.mark.timeout(120)
def test_a_run_planned_for_months_takes_the_memory_of_a_short_one(tmp_path: Path) -> None:
    config = load_config()
    stop = StopFlag()
    bus = in_process_bus(config, IMPACT, ())
    request = RunRequest(
        IMPACT, ControllerChoice("pid"), tmp_path, duration_s=1e7,
        on_progress=_stop_after(stop, 1.0),
    )  # fmt: skip
    tracemalloc.start()
    try:
        result = run_experiment(
            config, request, bus, LockstepClock(config.loop.period_s), {}, stop=stop
        )
        _now, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert result.ending.text == "interrupted: test"
    assert peak < 30e6, f"peak {peak / 1e6:.0f} MB for a run stopped after 1 s"


def test_the_reference_past_the_horizon_is_the_experiments(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setattr(hil.loop.experiment_feed, "REFERENCE_AHEAD_TICKS", 50)
    config = load_config()
    _result, run = run_in_process(config, CONTACT, "gc+lqr+dob", tmp_path, duration_s=3.0)
    time = run.columns["time_s"]
    expected = [CONTACT.reference(t - run.data.experiment_start_s) for t in time]
    phase = run.columns["phase"]
    held = phase == "experiment"
    assert held.sum() > 400
    np.testing.assert_allclose(
        run.columns["reference_rad"][held], np.array(expected)[held], rtol=0, atol=1e-9
    )
