"""The sweep's plan without Ray: specs, points, run ids, the configuration at a point, the
results table and the relations at a point (from rows made here, where the verdicts are known).
"""

from __future__ import annotations

import pytest

from hil.config import load_config
from hil.sweep import (
    ModelFollows,
    Sampling,
    SpecError,
    TableMismatch,
    load_spec,
    parse_spec,
    plan,
    shipped_specs,
)
from hil.sweep.plan import config_at, resolved
from hil.sweep.relations import fractions, point_relations
from hil.sweep.spec import parse_controller
from hil.sweep.table import ResultsTable, header
from hil.vocabulary import ControllerKind
from hil.wiring.emulation import plant_servo_noise

CONFIG = load_config()
GRID = """
title = "t"
experiments = ["impact"]
controllers = ["pid", "gc+lqr+dob@1"]
[sampling]
method = "grid"
[[parameter]]
name = "Kp"
targets = ["emulator.servo.position_gain_per_s"]
values = [8.0, 12.0]
[[parameter]]
name = "K"
targets = ["emulator.plant.gear_stiffness_nm_per_rad"]
relative = [0.5, 1.5]
points = 3
"""
MONTE_CARLO = """
experiments = ["contact", "impact"]
controllers = ["pid"]
model = "plant"
[base]
"safety.current_guard" = false
[sampling]
method = "monte-carlo"
count = 5
seed = 3
[[parameter]]
name = "D"
targets = ["emulator.plant.gear_damping_nms_per_rad"]
relative = [0.7, 1.3]
[[parameter]]
name = "reading"
targets = ["controller.composition"]
values = ["accumulated", "literal"]
"""


def test_a_grid_is_every_combination_and_relative_ranges_scale_the_configured_value() -> None:
    spec = resolved(parse_spec(GRID, "grid"), CONFIG)
    points = spec.points()
    assert len(points) == 6
    assert sorted({p["K"] for p in points}) == pytest.approx([1000.0, 2000.0, 3000.0])
    assert {p["Kp"] for p in points} == {8.0, 12.0}
    assert spec.axes == ("Kp", "K")


def test_monte_carlo_points_are_reproducible_and_within_the_range() -> None:
    spec = resolved(parse_spec(MONTE_CARLO, "mc"), CONFIG)
    assert spec.sampling is Sampling.MONTE_CARLO
    first, again = spec.points(), spec.points()
    assert first == again and len(first) == 5
    assert all(70.0 <= p["D"] <= 130.0 for p in first)
    assert {p["reading"] for p in first} <= {"accumulated", "literal"}


def test_run_ids_are_stable_and_name_everything_that_defines_a_run() -> None:
    spec = parse_spec(GRID, "grid")
    tasks = plan(spec, CONFIG)
    assert len(tasks) == 6 * 2
    assert [t.run_id for t in tasks] == [t.run_id for t in plan(spec, CONFIG)]
    assert len({t.run_id for t in tasks}) == len(tasks)
    assert len({t.point_id for t in tasks}) == 6
    shorter = parse_spec(GRID.replace('title = "t"', 'title = "t"\nduration_s = 2.0'), "g")
    assert not {t.run_id for t in plan(shorter, CONFIG)} & {t.run_id for t in tasks}


def test_the_configuration_at_a_point_sets_plant_servo_and_model() -> None:
    targets = {
        "emulator.servo.position_gain_per_s": 15.0,
        "emulator.plant.load_mass_kg": 2.0,
        "controller.composition": "literal",
    }
    nominal = config_at(CONFIG, targets, ModelFollows.NOMINAL)
    plant, servo, _ = plant_servo_noise(nominal)
    assert servo.position_gain_per_s == 15.0 and plant.load_mass_kg == 2.0
    assert nominal.controller.composition == "literal"
    assert nominal.model == CONFIG.model  # the controller keeps the configured model
    follows = config_at(CONFIG, targets, ModelFollows.PLANT)
    assert follows.model.servo_gain_per_s == 15.0
    assert follows.model.link_inertia_kg_m2 == pytest.approx(plant.link_inertia_kg_m2)
    assert follows.model.gravity_moment_kg_m == pytest.approx(plant.gravity_moment_kg_m)


def test_bad_specs_are_refused_with_the_key_named() -> None:
    with pytest.raises(SpecError, match="unknown experiment"):
        parse_spec(GRID.replace('["impact"]', '["walk"]'), "x")
    with pytest.raises(SpecError, match="controller"):
        parse_spec(GRID.replace('"pid"', '"pd"'), "x")
    with pytest.raises(SpecError, match="unknown keys"):
        parse_spec('colour = "red"\n' + GRID, "x")
    with pytest.raises(SpecError, match="parameter 'K': unknown keys"):
        parse_spec(GRID + 'colour = "red"\n', "x")
    with pytest.raises(SpecError, match="no such configuration key"):
        plan(
            parse_spec(GRID.replace("emulator.servo.position", "model.servo_position"), "x"), CONFIG
        )
    with pytest.raises(SpecError, match="has no"):
        plan(parse_spec(GRID.replace("position_gain_per_s", "gain"), "x"), CONFIG)
    with pytest.raises(SpecError, match="neither a TOML file nor a shipped spec"):
        load_spec("no-such-spec")


def test_the_shipped_specs_parse_and_plan() -> None:
    assert {"robustness", "ringing", "smoke"} <= set(shipped_specs())
    for name in shipped_specs():
        spec = load_spec(name)
        assert plan(spec, CONFIG)
    robustness = resolved(load_spec("robustness"), CONFIG)
    assert robustness.model is ModelFollows.NOMINAL
    for parameter in robustness.parameters:  # +-30 % of the configured plant
        nominal = {"K": 2000.0, "D": 100.0, "Kp": 10.0}[parameter.name]
        assert (parameter.low, parameter.high) == pytest.approx((0.7 * nominal, 1.3 * nominal))


def test_controllers_are_written_kind_at_kdist_slash_reading() -> None:
    choice = parse_controller("gc+lqr+dob@0.5/literal")
    assert (choice.kind, choice.kdist, choice.reading) == (
        ControllerKind.GC_LQR_DOB,
        0.5,
        "literal",
    )
    assert parse_controller("pid").kind is ControllerKind.PID


def _row(run_id: str, point: str, controller: str, ending: str, **metrics: object) -> dict:
    return {
        "run_id": run_id,
        "point_id": point,
        "Kp": 10.0,
        "experiment": "impact",
        "controller": controller,
        "ending": ending,
        "ran_its_course": ending in ("completed", "safety stop"),
        "error": "boom" if ending == "failed" else "",
        "wall_time_s": 1.0,
        "out_dir": "",
        "metrics": metrics,
    }


def test_the_table_keeps_rows_drops_a_cut_line_and_refuses_another_sweep(tmp_path) -> None:
    columns = header(["Kp"], ["impact"])
    table = ResultsTable(tmp_path, columns)
    table.append(_row("a", "p", "pid", "completed", first_peak_rad=0.02, oscillations=3))
    table.append(_row("b", "p", "pid", "failed"))
    with open(table.path, "a") as f:
        f.write("c,p,10.0,impact,pid,compl")  # Ctrl-C in the middle of a write
    again = ResultsTable(tmp_path, columns)
    assert set(again.rows) == {"a", "b"}
    assert again.rows["a"]["metrics"]["oscillations"] == 3
    assert again.rows["a"]["first_peak_rad"] == 0.02
    assert again.rows["b"]["ending"] == "failed" and again.rows["b"]["error"] == "boom"
    assert table.path.read_text().endswith("\n")
    with pytest.raises(TableMismatch):
        ResultsTable(tmp_path, header(["K"], ["impact"]))


def test_relations_at_each_point_and_their_fractions() -> None:
    """Two points: pid rings at the first (3 half-periods) and not at the second; the DOB's
    run fails at the second, so its relations there are not checked."""
    rows = [
        _row("1", "p1", "pid", "completed", first_peak_rad=0.02, oscillations=3,
             settling_time_s=2.0),
        _row("2", "p1", "gc+lqr+dob@1", "completed", first_peak_rad=0.04, oscillations=1,
             settling_time_s=1.0),
        _row("3", "p2", "pid", "completed", first_peak_rad=0.02, oscillations=0,
             settling_time_s=1.0),
        _row("4", "p2", "gc+lqr+dob@1", "failed"),
    ]  # fmt: skip
    found = point_relations(rows, ["impact"], ["Kp"])
    by_claim = {f.claim: f for f in fractions(found)}
    rings = by_claim["pid rings after the push"]
    assert (rings.holds, rings.does_not_hold, rings.fraction) == (1, 1, 0.5)
    peak = by_claim["first peak larger with gc+lqr+dob (Kdist 1) than with pid"]
    assert (peak.holds, peak.not_checked) == (1, 1)
    stable = by_claim["gc+lqr+dob (Kdist 1): the closed loop is stable after the push"]
    assert (stable.holds, stable.not_checked) == (1, 1)  # settled 1 s after the push, of 4 s


def test_a_run_that_raises_is_a_failed_row_with_the_error_not_nothing(tmp_path) -> None:
    """What checked_plan lets through can still fail in the worker: the row says so (here a
    task made by hand with a servo gain the emulator refuses)."""
    from dataclasses import replace

    from hil.sweep.task import FAILED, run_task

    (task,) = plan(parse_spec(GRID.replace("values = [8.0, 12.0]", "values = [8.0]"), "g"), CONFIG)[
        :1
    ]
    bad = replace(task, targets={"emulator.servo.position_gain_per_s": -1.0})
    row = run_task(bad, str(tmp_path))
    assert row["ending"] == FAILED and "position_gain_per_s" in row["error"]
    assert row["out_dir"] == ""  # refused before the run started: nothing written
