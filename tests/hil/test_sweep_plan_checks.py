"""The sweep's plan is validated and sized before Ray starts: every point's configuration is
checked once (a value the configuration or the emulator refuses is a bad spec, exit 2, not a
sweep of "failed" rows that exits 0), the run count is bounded with a clear message and found
without listing the points (a 1000^4 grid or count = 1e12 once ate 5 GB in 40 s), and the
command line's --max-runs and --address are judged at once."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from hil.cli import main
from hil.config import load_config
from hil.sweep import SpecError, parse_spec, plan
from hil.sweep.checks import MAX_SWEEP_RUNS, checked_plan, run_count

CONFIG = load_config()
HEAD = """
experiments = ["impact"]
controllers = ["pid"]
"""


def _grid(*parameters: str) -> str:
    return HEAD + '[sampling]\nmethod = "grid"\n' + "".join(parameters)


def _parameter(name: str, target: str, body: str) -> str:
    return f'[[parameter]]\nname = "{name}"\ntargets = ["{target}"]\n{body}\n'


KP = "emulator.servo.position_gain_per_s"


def test_a_grid_too_large_to_run_is_refused_at_once_without_listing_it() -> None:
    parameters = [
        _parameter(f"p{i}", target, "low = 1.0\nhigh = 2.0\npoints = 1000")
        for i, target in enumerate(
            [
                KP,
                "model.stiffness_nm_per_rad",
                "model.damping_nms_per_rad",
                "model.servo_gain_per_s",
            ]
        )  # fmt: skip
    ]
    spec = parse_spec(_grid(*parameters), "huge")
    assert run_count(spec) == 1000**4
    started = time.perf_counter()
    with pytest.raises(SpecError, match=rf"1000000000000 runs.*{MAX_SWEEP_RUNS}"):
        checked_plan(spec, CONFIG)
    assert time.perf_counter() - started < 1.0


@pytest.mark.parametrize("count", ["1e12", "1000000000000", "0", "-3", "true"])
def test_a_monte_carlo_count_must_be_a_whole_number_of_runs_within_the_bound(count: str) -> None:
    text = (
        HEAD + f'[sampling]\nmethod = "monte-carlo"\ncount = {count}\n'
        + _parameter("Kp", KP, "low = 8.0\nhigh = 12.0")
    )  # fmt: skip
    started = time.perf_counter()
    with pytest.raises(SpecError, match="count"):
        checked_plan(parse_spec(text, "mc"), CONFIG)
    assert time.perf_counter() - started < 1.0


@pytest.mark.parametrize(
    ("target", "values", "named"),
    [
        ("model.stiffness_nm_per_rad", '["abc"]', "stiffness_nm_per_rad"),
        ("emulator.plant.gear_stiffness_nm_per_rad", '[2000.0, "abc"]', "gear_stiffness"),
        ("safety.on_exit", "[3.0]", "on_exit"),
        (KP, "[8.0, -1.0]", "position_gain_per_s"),
    ],
)
def test_a_value_the_configuration_refuses_makes_the_spec_bad_naming_the_point(
    target: str, values: str, named: str
) -> None:
    spec = parse_spec(_grid(_parameter("x", target, f"values = {values}")), "bad")
    with pytest.raises(SpecError, match=named):
        checked_plan(spec, CONFIG)


@pytest.mark.parametrize(
    "body",
    [
        "low = -1.0\nhigh = 1.0\npoints = 3\nlog = true",  # a log scale through 0
        "low = 0.0\nhigh = 1.0\npoints = 3\nlog = true",
        "low = 2.0\nhigh = 1.0\npoints = 3",  # an empty range
        "low = 1.0\nhigh = nan\npoints = 3",
        "low = 1.0\nhigh = 2.0\npoints = 0",
        "low = 1.0\nhigh = 2.0\npoints = 2.5",
        "values = []",
    ],
)
def test_a_range_that_is_no_range_is_refused(body: str) -> None:
    with pytest.raises(SpecError, match="parameter 'x'"):
        plan(parse_spec(_grid(_parameter("x", "model.stiffness_nm_per_rad", body)), "r"), CONFIG)


def test_a_kdist_above_max_kdist_is_refused_at_plan_not_run_into_a_safety_stop() -> None:
    text = _grid(_parameter("Kp", KP, "values = [8.0]")).replace('["pid"]', '["gc+lqr+dob@5"]')
    with pytest.raises(SpecError, match="max_kdist"):
        checked_plan(parse_spec(text, "k"), CONFIG)


def test_a_valid_plan_is_every_run(tmp_path: Path) -> None:
    spec = parse_spec(_grid(_parameter("Kp", KP, "values = [8.0, 12.0]")), "ok")
    assert run_count(spec) == 2
    assert len(checked_plan(spec, CONFIG)) == 2


def _sweep(argv: list[str], capsys) -> tuple[int, str]:
    try:
        code = main(["sweep", *argv])
    except SystemExit as exc:
        code = int(exc.code or 0)
    return code, capsys.readouterr().err


def test_max_runs_below_zero_is_refused(tmp_path: Path, capsys) -> None:
    code, err = _sweep(["smoke", "--max-runs", "-1", "--out", str(tmp_path)], capsys)
    assert code == 2 and "--max-runs" in err
    assert not (tmp_path / "results.csv").exists()


def test_a_bad_spec_exits_2_before_ray_starts(tmp_path: Path, capsys) -> None:
    spec = tmp_path / "bad.toml"
    spec.write_text(_grid(_parameter("x", "safety.on_exit", "values = [3.0]")))
    code, err = _sweep([str(spec), "--out", str(tmp_path / "out")], capsys)
    assert code == 2 and "on_exit" in err, err
    assert not (tmp_path / "out" / "results.csv").exists()


@pytest.mark.timeout(60)
def test_an_unreachable_cluster_is_a_clear_error_within_seconds(tmp_path: Path, capsys) -> None:
    pytest.importorskip("ray")
    started = time.perf_counter()
    code, err = _sweep(["smoke", "--address", "127.0.0.1:1", "--out", str(tmp_path)], capsys)
    assert code == 2 and "127.0.0.1:1" in err and "cannot reach" in err, err
    assert time.perf_counter() - started < 15.0
