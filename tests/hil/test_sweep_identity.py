"""What a sweep's resume trusts, without Ray (max_runs = 0, or every run already done): the run
ids and sweep.json cover the base configuration's content, another configuration into the same
--out is refused (never reported as its own), one sweep at a time holds an --out, and two
(point, controller) pairs that are one run share one id and are run once."""

from __future__ import annotations

import fcntl
import json
import os
from pathlib import Path

import pytest

from hil.cli import main
from hil.config import default_config_text, load_config
from hil.sweep import parse_spec, plan, run_sweep
from hil.sweep.table import ResultsTable, header
from hil.sweep.task import task_row
from tests.hil.test_sweep_ray import TINY

CONFIG = load_config()
SPEC = TINY  # 2 points x 2 controllers
# a composition grid: a controller that names its reading runs the same at every composition,
# and pid reads none
COMPOSITION = """
experiments = ["impact"]
controllers = ["pid", "gc+lqr+dob@1", "gc+lqr+dob@1/accumulated-integral"]
[[parameter]]
name = "reading"
targets = ["controller.composition"]
values = ["accumulated", "literal", "accumulated-integral"]
"""


def _soft_config(tmp_path: Path) -> Path:
    """The built-in configuration with K = 500 instead of 2000 (the issue's soft.toml)."""
    text = default_config_text()
    assert "stiffness_nm_per_rad = 2000.0" in text
    path = tmp_path / "soft.toml"
    path.write_text(text.replace("stiffness_nm_per_rad = 2000.0", "stiffness_nm_per_rad = 500.0"))
    return path


def _finish_first_run(out: Path, spec_text: str) -> None:
    """A row for the spec's first run on the built-in configuration, as a worker writes it."""
    spec = parse_spec(spec_text, "identity")
    task = plan(spec, CONFIG)[0]
    table = ResultsTable(out, header(spec.parameter_names, spec.experiments))
    table.append(task_row(task, "completed", True, wall_time_s=1.0))


def test_run_ids_follow_the_base_configurations_content_not_its_path(tmp_path: Path) -> None:
    spec = parse_spec(SPEC, "identity")
    ids = [t.run_id for t in plan(spec, CONFIG)]
    soft = [t.run_id for t in plan(spec, load_config(_soft_config(tmp_path)))]
    assert not set(ids) & set(soft)  # K = 500 runs are not the K = 2000 runs
    same = tmp_path / "same.toml"
    same.write_text(default_config_text())
    assert [t.run_id for t in plan(spec, load_config(same))] == ids  # same content: same runs


def test_another_base_configuration_into_the_same_out_is_refused_naming_what_differs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    spec, out = tmp_path / "identity.toml", tmp_path / "out"
    spec.write_text(SPEC)
    command = ["sweep", str(spec), "--out", str(out), "--max-runs", "0"]
    assert main(command) == 1  # planned, nothing run: incomplete
    _finish_first_run(out, SPEC)
    capsys.readouterr()
    assert main(command) == 1
    assert "1 done before, 3 to run" in capsys.readouterr().err  # the same sweep resumes

    assert main([*command, "--config", str(_soft_config(tmp_path))]) == 2
    err = capsys.readouterr().err
    assert "done before" not in err  # K = 2000's results are not reported as K = 500's
    assert "holds the results of another sweep" in err
    assert "model.stiffness_nm_per_rad = 500.0 here, 2000.0 there" in err
    assert len((out / "results.csv").read_text().splitlines()) == 2  # left as it was
    assert json.loads((out / "sweep.json").read_text())["configuration"]["model"][
        "stiffness_nm_per_rad"
    ] == pytest.approx(2000.0)


def test_a_second_sweep_into_a_busy_out_is_refused_and_the_lock_goes_with_the_sweep(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    spec, out = parse_spec(SPEC, "identity"), tmp_path / "out"
    out.mkdir()
    holder = os.open(out / "sweep.lock", os.O_RDWR | os.O_CREAT)  # another sweep's lock
    try:
        fcntl.flock(holder, fcntl.LOCK_EX | fcntl.LOCK_NB)
        os.write(holder, b"4242\n")
        with pytest.raises(RuntimeError, match=r"in use by another sweep \(pid 4242\)"):
            run_sweep(spec, CONFIG, out, max_runs=0)
        assert not (out / "results.csv").exists()  # nothing read or written meanwhile
        spec_path = tmp_path / "identity.toml"
        spec_path.write_text(SPEC)
        assert main(["sweep", str(spec_path), "--out", str(out), "--max-runs", "0"]) == 2
        assert "in use by another sweep" in capsys.readouterr().err
    finally:
        os.close(holder)
    run_sweep(spec, CONFIG, out, max_runs=0)  # free again: the sweep takes it ...
    probe = os.open(out / "sweep.lock", os.O_RDWR)
    try:
        fcntl.flock(probe, fcntl.LOCK_EX | fcntl.LOCK_NB)  # ... and gives it back on return
    finally:
        os.close(probe)
    with pytest.raises(ValueError, match="another sweep"):
        run_sweep(spec, load_config(_soft_config(tmp_path)), out, max_runs=0)
    probe = os.open(out / "sweep.lock", os.O_RDWR)
    try:
        fcntl.flock(probe, fcntl.LOCK_EX | fcntl.LOCK_NB)  # and when it raises
    finally:
        os.close(probe)


def test_a_composition_grid_runs_each_distinct_run_once() -> None:
    tasks = plan(parse_spec(COMPOSITION, "composition"), CONFIG)
    assert len(tasks) == 9
    by_pair = {(t.values["reading"], t.controller): t.run_id for t in tasks}
    named = by_pair[("accumulated-integral", "gc+lqr+dob@1")]
    # "gc+lqr+dob@1/accumulated-integral" at every point is "gc+lqr+dob@1" at that reading
    assert {by_pair[(r, "gc+lqr+dob@1/accumulated-integral")] for r in
            ("accumulated", "literal", "accumulated-integral")} == {named}  # fmt: skip
    assert len({by_pair[(r, "pid")] for r in ("accumulated", "literal")}) == 1  # reads none
    dob = {by_pair[(r, "gc+lqr+dob@1")] for r in ("accumulated", "literal", "accumulated-integral")}
    assert len(dob) == 3  # the reading it does read: three runs
    assert len({t.run_id for t in tasks}) == 4


def test_the_integral_time_counts_only_for_the_reading_that_reads_it() -> None:
    spec = parse_spec(
        COMPOSITION.replace(', "literal"', "").replace(
            '"pid", "gc+lqr+dob@1", "gc+lqr+dob@1/accumulated-integral"', '"gc+lqr+dob@1"'
        )
        + '[[parameter]]\nname = "Ti_d"\ntargets = ["controller.dob_integral_time_s"]\n'
        "values = [10.0, 20.0]\n",
        "integral",
    )
    tasks = plan(spec, CONFIG)
    ids = {(t.values["reading"], t.values["Ti_d"]): t.run_id for t in tasks}
    assert ids[("accumulated", 10.0)] == ids[("accumulated", 20.0)]
    assert ids[("accumulated-integral", 10.0)] != ids[("accumulated-integral", 20.0)]


def test_a_sweep_counts_and_schedules_each_run_once(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # a Monte Carlo draw of three choices, six times: repeated points are one run each
    spec = tmp_path / "drawn.toml"
    spec.write_text(
        COMPOSITION.replace('"gc+lqr+dob@1", "gc+lqr+dob@1/accumulated-integral"', '"gc+lqr"')
        + '[sampling]\nmethod = "monte-carlo"\ncount = 6\nseed = 0\n'
    )
    drawn = plan(parse_spec(spec.read_text(), "drawn"), CONFIG)
    distinct = {t.run_id for t in drawn}
    readings = {t.values["reading"] for t in drawn}
    assert len(drawn) == 12 and len(distinct) == 1 + len(readings) < 12
    out = tmp_path / "out"
    assert main(["sweep", str(spec), "--out", str(out), "--max-runs", "0"]) == 1
    err = capsys.readouterr().err
    assert f"0 done before, {len(distinct)} to run" in err, err
    assert json.loads((out / "summary.json").read_text())["runs"] == len(distinct)
