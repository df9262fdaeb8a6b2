"""`hil compare` end to end on real runs through the embedded emulator (two testbed contact
runs, two short humanoid stands, a plug-in controller's run, a run with another seed): the
table holds each run's metrics from its summary.json and how it ended, the figures exist and
report.md shows them; runs of different experiments, a directory that is not a run, one run
alone or twice are refused with exit 2 and a message naming them; a run with a torn or missing
summary.json, or whose log lacks a signal, is compared and said so."""

from __future__ import annotations

import csv
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import hil
from hil.cli import main
from hil.output.run_data import load_run
from hil.session.compare_runs import compare_runs

ROOT = Path(__file__).resolve().parents[2]
PD = "examples/pd_gravity.py:PdGravity"


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    out = tmp_path_factory.mktemp("runs")
    testbed = hil.open_robot(robot="testbed", out_root=out / "testbed")
    seeded = hil.open_robot(robot="testbed", out_root=out / "seeded", seed=7)
    humanoid = hil.open_robot(robot="dyros-jet", out_root=out / "humanoid")
    return {
        "pid": testbed.run("contact", "pid", duration_s=4.0).out_dir,
        "dob": testbed.run("contact", "gc+lqr+dob", duration_s=4.0).out_dir,
        "plugin": testbed.run("contact", str(ROOT / PD), duration_s=4.0).out_dir,
        "pid-seed-7": seeded.run("contact", "pid", duration_s=4.0).out_dir,
        "stand-pid": humanoid.run("stand", "pid", duration_s=2.0).out_dir,
        "stand-dob": humanoid.run("stand", "gc+lqr+dob", duration_s=2.0).out_dir,
    }


def _compare(capsys: pytest.CaptureFixture[str], *args: object) -> tuple[int, str, str]:
    code = main(["compare", *map(str, args)])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def _row(out: str, label: str) -> str:
    return next(line for line in out.splitlines() if f"  {label}  " in f" {line} ")


def test_two_testbed_runs(runs: dict[str, Path], tmp_path: Path, capsys) -> None:
    code, out, _ = _compare(capsys, runs["pid"], runs["dob"], "--out", tmp_path)
    assert code == 0
    pid, dob = load_run(runs["pid"]), load_run(runs["dob"])
    pid_row, dob_row = _row(out, "pid"), _row(out, "gc+lqr+dob (Kdist 1)")
    assert f"{pid.metrics['peak_contact_force_n']:.1f}" in pid_row  # the run's own figures
    assert f"{dob.metrics['peak_contact_force_n']:.1f}" in dob_row
    first_stop = pid.safety_events[0]["time_s"]
    assert pid_row.endswith(f"safety stop: current (back_off) at {first_stop:.3f} s")
    assert dob_row.endswith("completed")
    report = (tmp_path / "report.md").read_text()
    for figure in ("fig5_contact.png", "signals.png"):
        assert (tmp_path / figure).stat().st_size > 10_000 and f"]({figure})" in report
    assert "| 1 | pid |" in report and "`kdist`: #1 0.0, #2 1.0" in report


def test_two_humanoid_stands(runs: dict[str, Path], tmp_path: Path, capsys) -> None:
    code, out, _ = _compare(capsys, runs["stand-pid"], runs["stand-dob"], "--out", tmp_path)
    assert code == 0
    for key, label in (("stand-pid", "pid"), ("stand-dob", "gc+lqr+dob (Kdist 0.2)")):
        tilt = load_run(runs[key]).metrics["pelvis_tilt_rad"]
        assert f"{tilt:.4f}" in _row(out, label)
    report = (tmp_path / "report.md").read_text()
    for figure in ("stand.png", "joints.png", "kinematics.png"):
        assert (tmp_path / figure).stat().st_size > 10_000 and f"]({figure})" in report


def test_a_plug_in_and_another_seed_are_named_by_their_record(
    runs: dict[str, Path], tmp_path: Path
) -> None:
    comparison = compare_runs([runs["pid"], runs["pid-seed-7"], runs["plugin"]], tmp_path)
    labels = [entry.label for entry in comparison.runs]
    assert labels == [
        f"pid ({runs['pid'].name})",
        f"pid ({runs['pid-seed-7'].name})",
        "PdGravity",
    ]
    styles = [(entry.style.color, entry.style.linestyle) for entry in comparison.runs]
    assert len(set(styles)) == 3  # one line each, none the grey of an unknown controller
    assert styles[0] == ("tab:blue", ":")  # the paper's style for its pid
    report = (tmp_path / "report.md").read_text()
    assert "`seed`: #1 " in report and "#2 7" in report
    assert "PdGravity" in comparison.table_text


def test_runs_of_different_experiments_are_refused(runs: dict[str, Path], capsys) -> None:
    code, _, err = _compare(capsys, runs["pid"], runs["stand-pid"])
    assert code == 2
    assert "different experiments" in err and "contact: " in err and "stand: " in err
    assert str(runs["pid"]) in err and str(runs["stand-pid"]) in err


def test_what_is_not_a_pair_of_runs_is_refused(
    runs: dict[str, Path], tmp_path: Path, capsys
) -> None:
    code, _, err = _compare(capsys, runs["pid"], tmp_path)
    assert code == 2 and f"{tmp_path} is not a run directory" in err
    code, _, err = _compare(capsys, runs["pid"])
    assert code == 2 and "two or more run directories" in err
    code, _, err = _compare(capsys, runs["pid"], runs["pid"])
    assert code == 2 and "given twice" in err
    assert not list(tmp_path.iterdir())  # nothing written


def test_the_command_exits_2_before_writing(runs: dict[str, Path], tmp_path: Path) -> None:
    command = [sys.executable, "-m", "hil", "compare", str(runs["pid"]), str(tmp_path / "x")]
    done = subprocess.run(command, capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert done.returncode == 2 and "no such directory" in done.stderr
    assert "Traceback" not in done.stderr and not (tmp_path / "runs").exists()


def test_a_torn_or_missing_summary_is_said(runs: dict[str, Path], tmp_path: Path, capsys) -> None:
    torn = shutil.copytree(runs["dob"], tmp_path / "torn")
    text = (torn / "summary.json").read_text()
    (torn / "summary.json").write_text(text[:200])
    missing = shutil.copytree(runs["pid"], tmp_path / "missing")
    (missing / "summary.json").unlink()
    code, out, _ = _compare(capsys, missing, torn, "--out", tmp_path / "out")
    assert code == 0
    assert "unknown: summary.json is torn (not whole JSON)" in out
    assert "unknown: no summary.json: the run did not finish writing its record" in out
    assert (tmp_path / "out" / "signals.png").is_file()


def test_a_run_whose_log_lacks_a_signal_is_compared(
    runs: dict[str, Path], tmp_path: Path, capsys
) -> None:
    lacking = shutil.copytree(runs["dob"], tmp_path / "lacking")
    with open(runs["dob"] / "log.csv", newline="") as f:
        rows = list(csv.reader(f))
    drop = rows[0].index("motor_current_a")
    with open(lacking / "log.csv", "w", newline="") as f:
        csv.writer(f, lineterminator="\n").writerows([r[:drop] + r[drop + 1 :] for r in rows])
    code, out, _ = _compare(capsys, runs["pid"], lacking, "--out", tmp_path / "out")
    assert code == 0
    assert "note: gc+lqr+dob (Kdist 1): its log has no motor_current_a" in out
    assert (tmp_path / "out" / "signals.png").is_file()


def test_runs_the_paper_styles_cannot_tell_apart_get_a_colour_no_other_run_has() -> None:
    from hil.session.compare_runs import _styles
    from hil.vocabulary import ControllerChoice, ControllerKind

    # two GC runs (the record does not say the compliance of (8) apart from the label) and pid
    styles = _styles([ControllerChoice(ControllerKind.GC)] * 2 + [ControllerChoice("pid")])
    colours = [style.color for style in styles]
    assert colours[0] == "0.45" and colours[2] == "tab:blue"  # the paper's
    assert colours[1] not in (colours[0], colours[2])
