"""The sweep on a local Ray (1 or 2 CPUs): the table, the maps, resuming without repeating a
run, a failed run recorded as failed; and `hil sweep` without Ray. Ray is always shut down."""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import pytest

from hil.cli import main
from hil.config import load_config
from hil.sweep import parse_spec, plan, run_sweep

CONFIG = load_config()
TINY = """
title = "tiny"
experiments = ["impact"]
controllers = ["pid", "gc+lqr+dob@1"]
duration_s = 2.5
[sampling]
method = "grid"
[[parameter]]
name = "Kp"
targets = ["emulator.servo.position_gain_per_s"]
values = [8.0, 12.0]
"""


def _lines(path: Path) -> list[str]:
    return path.read_text().splitlines()


@pytest.mark.slow
@pytest.mark.ray
@pytest.mark.timeout(600)
def test_a_tiny_sweep_resumes_without_repeating(tmp_path: Path) -> None:
    ray = pytest.importorskip("ray")
    spec = parse_spec(TINY, "tiny")
    run_ids = [t.run_id for t in plan(spec, CONFIG)]
    try:
        partial = run_sweep(spec, CONFIG, tmp_path, workers=1, max_runs=2)
        assert (partial.done_now, partial.complete) == (2, False)
        first_rows = _lines(tmp_path / "results.csv")[1:]
        assert len(first_rows) == 2

        full = run_sweep(spec, CONFIG, tmp_path, workers=2)
    finally:
        ray.shutdown()
    assert not ray.is_initialized()
    assert (full.done_before, full.done_now, full.complete) == (2, 2, True)
    lines = _lines(tmp_path / "results.csv")
    assert lines[1:3] == first_rows  # the finished runs were kept, not redone
    with open(tmp_path / "results.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert sorted(r["run_id"] for r in rows) == sorted(run_ids)  # each run exactly once
    assert full.failed == 0
    assert all(r["ending"] == "completed" and float(r["first_peak_rad"]) > 0 for r in rows)

    assert (tmp_path / "maps" / "impact.png").read_bytes()[:4] == b"\x89PNG"
    summary = json.loads((tmp_path / "summary.json").read_text())
    stable = next(r for r in summary["relations"] if "stable after the push" in r["claim"])
    assert (stable["holds"], stable["not_checked"]) == (2, 0)
    assert (tmp_path / "relations.csv").is_file()

    again = run_sweep(spec, CONFIG, tmp_path)  # nothing left: no Ray started at all
    assert (again.done_before, again.done_now) == (4, 0) and not ray.is_initialized()
    assert _lines(tmp_path / "results.csv") == lines


def test_without_ray_hil_sweep_says_how_to_install_it(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` raises ImportError
    assert main(["sweep", "smoke"]) == 2
    err = capsys.readouterr().err
    assert "pip install" in err and "[sweep]" in err


def test_hil_sweep_list_names_the_shipped_specs(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["sweep", "--list"]) == 0
    names = [line.split()[0] for line in capsys.readouterr().out.splitlines()]
    assert {"robustness", "ringing", "smoke"} <= set(names)


@pytest.mark.slow
@pytest.mark.ray
@pytest.mark.timeout(600)
def test_the_sweep_bench_measures_both_worker_counts_and_the_overhead() -> None:
    pytest.importorskip("ray")
    from hil.sweep.bench import run_bench_sweep, sweep_report_text

    report = run_bench_sweep(CONFIG, runs=2, repeats=1)
    rates = report["runs_per_minute"]
    assert all(rates[key] > 0 for key in ("plain", "ray_1", "ray_2"))
    assert report["scaling_2_over_1"] == pytest.approx(rates["ray_2"] / rates["ray_1"])
    # the runs' own time inside a worker is part of the elapsed time, not more
    assert report["seconds_inside_run"]["ray_1"] <= report["seconds_per_run"]["ray_1"]
    assert "scaling 2 workers / 1" in sweep_report_text(report)


# pid reads no composition, and the DOB names its reading: one run each at every point
COMPOSITION = TINY.replace('"gc+lqr+dob@1"', '"gc+lqr+dob@1/accumulated-integral"').replace(
    'name = "Kp"\ntargets = ["emulator.servo.position_gain_per_s"]\nvalues = [8.0, 12.0]',
    'name = "reading"\ntargets = ["controller.composition"]\n'
    'values = ["accumulated", "literal", "accumulated-integral"]',
)


@pytest.mark.slow
@pytest.mark.ray
@pytest.mark.timeout(600)
def test_a_composition_grid_runs_a_run_shared_by_its_points_once(tmp_path: Path) -> None:
    ray = pytest.importorskip("ray")
    assert "controller.composition" in COMPOSITION and "Kp" not in COMPOSITION
    try:
        outcome = run_sweep(parse_spec(COMPOSITION, "composition"), CONFIG, tmp_path, workers=1)
    finally:
        ray.shutdown()
    # 2 runs for 3 points x 2 controllers
    assert (outcome.total, outcome.done_now, outcome.complete) == (2, 2, True)
    with open(tmp_path / "results.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 2 and len({r["run_id"] for r in rows}) == 2
    with open(tmp_path / "relations.csv", newline="") as f:
        relations = list(csv.DictReader(f))
    assert {r["reading"] for r in relations} == {"accumulated", "literal", "accumulated-integral"}
    summary = json.loads((tmp_path / "summary.json").read_text())
    stable = next(r for r in summary["relations"] if "stable after the push" in r["claim"])
    assert stable["holds"] + stable["does_not_hold"] + stable["not_checked"] == 3  # per point
