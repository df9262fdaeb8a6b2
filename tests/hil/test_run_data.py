"""The run loader (hil/output/run_data.py) and the humanoid's per-tick kinematics.csv, on real
runs through the embedded emulator: every value the loader gives equals log.csv's cell as the
csv module reads it, the long table holds every (tick, joint) once, a run without (or with a
torn) summary.json still loads and says so, and kinematics.csv holds the figures the metrics
were computed from."""

from __future__ import annotations

import csv
import doctest
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

import hil
import hil.output.run_data as run_data
from hil.experiments import STAND, WALK_DYNAMIC
from hil.experiments.humanoid import SETTLE_S
from hil.output.run_data import NotARunDirectory, Table, load_run
from hil.output.series import KINEMATICS_COLUMNS


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    out = tmp_path_factory.mktemp("runs")
    testbed = hil.open_robot(robot="testbed", out_root=out / "testbed")
    humanoid = hil.open_robot(robot="dyros-jet", out_root=out / "humanoid")
    return {
        "contact": testbed.run("contact", "pid", duration_s=4.0).out_dir,
        "stand": humanoid.run("stand", "gc+lqr+dob", duration_s=2.0).out_dir,
        "walk": humanoid.run("walk-dynamic", "gc+lqr+dob", duration_s=3.0).out_dir,
    }


def _cells(path: Path) -> tuple[list[str], list[list[str]]]:
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


def _value(cell: str) -> object:
    try:
        return float(cell)
    except ValueError:
        return cell


@pytest.mark.parametrize("name", ["contact", "stand"])
def test_every_value_is_the_logs_cell(runs: dict[str, Path], name: str) -> None:
    run = load_run(runs[name])
    header, rows = _cells(runs[name] / "log.csv")
    assert run.ticks == len(rows) > 100
    seen = set()
    for index, column in enumerate(header):
        signal, _, joint = column.partition("[")
        joint = joint.rstrip("]") or None
        if signal in run.signals and joint is None:
            joint = run.joints[0]  # a one-joint log: the columns carry no name
        values = run.signal(signal, joint=joint)
        expected = [_value(r[index]) for r in rows]
        if values.dtype == bool:
            assert values.tolist() == [cell == 1.0 for cell in expected], column
        elif values.dtype == object:
            assert values.tolist() == expected, column
        else:
            np.testing.assert_array_equal(values, np.array(expected, dtype=float), column)
        seen.add((signal, joint))
    assert len(seen) == len(header)  # every column read, none twice


def test_a_one_joint_run_names_its_joint_and_types_its_columns(runs: dict[str, Path]) -> None:
    run = load_run(runs["contact"])
    assert (run.experiment, run.controller, run.joints) == ("contact", "pid", ("testbed",))
    assert run.signals[:4] == ("reference_rad", "goal_rad", "motor_angle_rad", "link_angle_rad")
    assert "contact_force_n" in run.run_signals and "link_angle_rad" not in run.run_signals
    assert run.signal("tick").dtype == np.int64 and run.signal("torque_enabled").dtype == bool
    assert run.signal("link_angle_rad", joint="testbed") is not None
    assert run.termination.startswith("safety stop") and not run.completed  # pid on the block
    assert run.safety_events[0]["cause"] == "current"
    with pytest.raises(KeyError, match="no joint 'L_HipYaw'"):
        run.signal("link_angle_rad", joint="L_HipYaw")
    with pytest.raises(ValueError, match="not a per-joint signal"):
        run.signal("contact_force_n", joint="testbed")
    with pytest.raises(KeyError, match="no signal 'zmp_x_m'"):
        run.signal("zmp_x_m")
    assert run.kinematics is None  # the testbed has no kinematics.csv


def test_the_humanoid_asks_for_a_joint(runs: dict[str, Path]) -> None:
    run = load_run(runs["stand"])
    assert len(run.joints) == 12 and run.joints[0] == "L_HipYaw"
    assert run.joint_signals("deflection_rad").shape == (run.ticks, 12)
    np.testing.assert_array_equal(
        run.joint_signals("link_angle_rad")[:, 3], run.signal("link_angle_rad", "L_KneePitch")
    )
    with pytest.raises(ValueError, match="12 joints: name one of"):
        run.signal("link_angle_rad")


@pytest.mark.parametrize("name", ["contact", "stand"])
def test_the_long_table_has_a_row_per_tick_and_joint(runs: dict[str, Path], name: str) -> None:
    run = load_run(runs[name])
    table = run.long()
    header, rows = _cells(runs[name] / "log.csv")
    n = len(run.joints)
    assert len(table) == run.ticks * n
    assert table.names[:3] == ("tick", "time_s", "joint")
    assert set(table.names) == {"joint", *run.signals, *run.run_signals}
    # tick-major: row (tick k, joint j) is k * n + j; each cell the log's
    for k in (0, 1, run.ticks // 2, run.ticks - 1):
        for j, joint in enumerate(run.joints):
            row = table.to_records()[k * n + j]
            assert (row["tick"], row["joint"]) == (int(rows[k][0]), joint)
            column = "link_angle_rad" if n == 1 else f"link_angle_rad[{joint}]"
            assert row["link_angle_rad"] == float(rows[k][header.index(column)])
            assert row["phase"] == rows[k][header.index("phase")]


def test_the_long_table_in_pandas(runs: dict[str, Path]) -> None:
    pandas = pytest.importorskip("pandas")
    run = load_run(runs["stand"])
    frame = run.long().to_pandas()
    assert isinstance(frame, pandas.DataFrame) and len(frame) == run.ticks * 12
    means = frame.groupby("joint")["deflection_rad"].mean()
    assert means["R_KneePitch"] == pytest.approx(run.signal("deflection_rad", "R_KneePitch").mean())


def test_to_pandas_without_pandas_says_how_to_get_it(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "pandas", None)  # import pandas raises ImportError
    with pytest.raises(ImportError, match=r"pip install 'flexjoint-hil\[analysis\]'"):
        Table({"x": np.zeros(2)}).to_pandas()


def test_a_run_without_a_whole_summary_loads_and_says_so(
    runs: dict[str, Path], tmp_path: Path
) -> None:
    torn = shutil.copytree(runs["contact"], tmp_path / "torn")
    text = (torn / "summary.json").read_text()
    (torn / "summary.json").write_text(text[: len(text) // 2])
    missing = shutil.copytree(runs["contact"], tmp_path / "missing")
    (missing / "summary.json").unlink()
    for path, why in ((torn, "torn"), (missing, "no summary.json")):
        run = load_run(path)
        assert why in run.summary_problem and why in run.termination
        assert run.metrics == {} and not run.completed
        assert run.ticks == load_run(runs["contact"]).ticks  # the log is all there


def test_a_directory_that_is_not_a_run_is_refused(tmp_path: Path) -> None:
    with pytest.raises(NotARunDirectory, match="no such directory"):
        load_run(tmp_path / "nowhere")
    with pytest.raises(NotARunDirectory, match="holds no log.csv"):
        load_run(tmp_path)
    (tmp_path / "log.csv").write_text("a,b\n1,2\n")
    with pytest.raises(NotARunDirectory, match="no time_s column"):
        load_run(tmp_path)


def test_the_docstring_examples_run(runs: dict[str, Path]) -> None:
    failures, tried = doctest.testmod(
        run_data, extraglobs={"path": runs["contact"]}, optionflags=doctest.ELLIPSIS
    )
    assert tried > 10 and failures == 0


# --- kinematics.csv ---------------------------------------------------------------------------
def test_the_stands_kinematics_are_what_its_metrics_saw(runs: dict[str, Path]) -> None:
    run = load_run(runs["stand"])
    kinematics = run.kinematics
    assert kinematics is not None and kinematics.names == KINEMATICS_COLUMNS
    np.testing.assert_array_equal(kinematics["tick"], run.signal("tick"))
    np.testing.assert_array_equal(kinematics["time_s"], run.time_s)
    settled = run.time_s >= SETTLE_S
    error = np.hypot(
        kinematics["zmp_x_m"] - kinematics["desired_zmp_x_m"],
        kinematics["zmp_y_m"] - kinematics["desired_zmp_y_m"],
    )
    metrics = run.metrics
    assert np.nanmax(kinematics["pelvis_tilt_rad"][settled]) == pytest.approx(
        metrics["pelvis_tilt_rad"], abs=2e-9
    )
    assert np.nanmax(error[settled]) == pytest.approx(metrics["zmp_max_error_m"], abs=2e-9)
    # the desired ZMP is the posture's CoM on the ground; the robot stands on both feet
    desired = STAND._desired_zmp()
    np.testing.assert_allclose(kinematics["desired_zmp_x_m"], desired[0], atol=1e-9)
    feet = kinematics["left_foot_vertical_n"] + kinematics["right_foot_vertical_n"]
    assert run.completed
    assert np.all(feet[settled] > 0.8 * STAND._weight_n())
    assert np.all(kinematics["support_margin_m"][settled] > 0)
    # the CoM at the measured angles stays near the desired one's ground point
    com = np.column_stack([kinematics["com_x_m"], kinematics["com_y_m"]])[settled]
    assert np.max(np.linalg.norm(com - desired, axis=1)) < 0.02
    assert 0.7 < np.nanmedian(kinematics["com_z_m"]) < 0.9


def test_the_walks_kinematics_are_what_its_metrics_saw(runs: dict[str, Path]) -> None:
    run = load_run(runs["walk"])
    kinematics = run.kinematics
    assert kinematics is not None and len(kinematics) == run.ticks  # no re-homing: every row
    dt = WALK_DYNAMIC.pattern.dt_s
    start, end = (t * dt for t in WALK_DYNAMIC.walk_ticks)
    time_s = kinematics["time_s"] - run.summary["experiment_start_s"]
    walking = (time_s >= start) & (time_s < end)
    error = np.hypot(
        kinematics["zmp_x_m"] - kinematics["desired_zmp_x_m"],
        kinematics["zmp_y_m"] - kinematics["desired_zmp_y_m"],
    )
    assert np.max(error[walking]) == pytest.approx(run.metrics["zmp_max_error_m"], abs=2e-9)
    planned = WALK_DYNAMIC.pattern.zmp_reference_m[np.rint(time_s / dt).astype(int)]
    np.testing.assert_allclose(kinematics["desired_zmp_y_m"], planned[:, 1], atol=1e-9)
