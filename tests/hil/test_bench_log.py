"""`hil bench log`: the three cases measured side by side, the live case with a viewer that
received every per-tick message."""

from __future__ import annotations

import pytest

from hil.bench.log import CASES, ROUNDS, log_report_text, run_bench_log
from hil.config import load_config


@pytest.mark.timeout(120)
def test_bench_log_measures_every_case_with_a_viewer() -> None:
    ticks = 40
    report = run_bench_log(load_config(), ticks)
    assert [case["case"] for case in report["cases"]] == list(CASES)
    for case in report["cases"]:
        assert case["ticks"] >= ROUNDS * ticks  # tick 0 left out; hold/stop ticks added
        assert 0 < case["log"]["median_s"] < 0.05
    assert report["viewer"]
    # /joints, /loop and /timing per tick, plus events, meta and summary: nothing dropped
    per_run = report["cases"][2]["ticks"] // ROUNDS + 1
    received = report["viewer_messages_received"]
    assert all(count >= 3 * per_run for count in received), (received, per_run)
    assert "csv+mcap+live" in log_report_text(report)
