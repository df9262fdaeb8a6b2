"""A comparison's runs in worker processes, each through its own embedded emulator: the same
logs and report as one after the other, and a stop in the middle (Ctrl-C to the terminal's
process group, SIGTERM to `hil run` alone) that ends every running run through its exit path
and leaves no process behind."""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from hil.cli import main
from hil.config import load_config
from hil.experiments import CONTACT, IMPACT
from hil.robots import profile
from hil.session import Session, Setup
from hil.session.comparison import run_plan, write_comparison_report
from hil.sweep.processes import descendants
from hil.vocabulary import ControllerChoice, ControllerKind
from tests.support.rig import assert_log_complete, load_run

TESTBED = profile("testbed").comparison()  # the testbed's own comparison and report

PLAN = [
    (dataclasses.replace(IMPACT, duration_s=1.5), ControllerChoice(ControllerKind.PID)),
    (dataclasses.replace(IMPACT, duration_s=1.5), ControllerChoice(ControllerKind.GC_LQR_DOB, 1)),
    (dataclasses.replace(CONTACT, duration_s=3.0), ControllerChoice(ControllerKind.GC)),
]


def _comparison(root: Path, workers: int) -> dict:
    session = Session(load_config(), Setup.EMBEDDED, out_root=root, quiet=True)
    outcome = run_plan(session, PLAN, root, workers=workers)
    assert outcome.incomplete is None
    report = write_comparison_report(root, outcome.entries, session.description, 0.0, TESTBED)
    return json.loads(json.dumps(report.summary).replace(str(root), "ROOT"))


@pytest.mark.slow
def test_two_workers_write_the_logs_and_the_report_of_one_after_the_other(tmp_path: Path) -> None:
    serial = _comparison(tmp_path / "serial", workers=1)
    parallel = _comparison(tmp_path / "parallel", workers=2)
    assert parallel == serial  # run by run, in plan order, the same metrics and relations
    runs = sorted(p.name for p in (tmp_path / "serial").iterdir() if p.is_dir())
    assert len(runs) == 3
    for run in runs:
        for name in ("log.csv", "events.jsonl"):
            one = (tmp_path / "serial" / run / name).read_bytes()
            assert (tmp_path / "parallel" / run / name).read_bytes() == one, f"{run}/{name}"
        assert (tmp_path / "parallel" / run / "plot.png").is_file()  # drawn in the worker


def _started(pid: int) -> int | None:
    """The start time of a live process (clock ticks since boot), None once it is gone."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    fields = stat[stat.rindex(")") + 2 :].split()
    return None if fields[0] == "Z" else int(fields[19])


def _still_running(processes: set[tuple[int, int]]) -> set[tuple[int, int]]:
    """Those of `processes` still running after a grace period: multiprocessing's resource
    tracker leaves when `hil run` has gone (it reads the end of its pipe), a moment later."""
    deadline = time.monotonic() + 10
    while (left := {p for p in processes if _started(p[0]) == p[1]}) and (
        time.monotonic() < deadline
    ):
        time.sleep(0.1)
    return left


def _logs_with_rows(out: Path, rows: int) -> list[Path]:
    logs = out.glob("*-comparison/*/log.csv")
    return [log for log in logs if log.read_text().count("\n") > rows]


@pytest.mark.timeout(240)
@pytest.mark.parametrize("signame", ["SIGINT", "SIGTERM"])
def test_a_stopped_comparison_stops_every_run_through_its_exit_path_and_leaves_no_process(
    tmp_path: Path, signame: str
) -> None:
    out = tmp_path / "runs"
    command = [
        sys.executable,
        "-m",
        "hil",
        "run",
        "--workers",
        "2",
        "--no-plots",
        "--out",
        str(out),
    ]
    process = subprocess.Popen(
        command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True
    )
    deadline = time.monotonic() + 120
    while len(_logs_with_rows(out, 100)) < 2:  # both workers in a run
        assert process.poll() is None and time.monotonic() < deadline
        time.sleep(0.1)
    below = descendants(process.pid)  # the workers, their emulators, multiprocessing's tracker
    assert len(below) >= 4, below
    if signame == "SIGINT":
        os.killpg(process.pid, signal.SIGINT)  # a terminal's Ctrl-C: the whole group
    else:
        process.send_signal(signal.SIGTERM)  # to `hil run` alone: passed on to the workers
    stdout, stderr = process.communicate(timeout=120)
    assert process.returncode == 1, stderr
    assert "Traceback" not in stderr, stderr
    assert not _still_running(below)
    assert f"comparison incomplete: impact-long / gc+lqr+dob (Kdist 1): interrupted: {signame}" in (
        stdout
    )
    (root,) = out.iterdir()
    runs = [load_run(d, process.returncode) for d in sorted(root.iterdir()) if d.is_dir()]
    assert len(runs) == 2  # the two running runs; none began after the signal
    for run in runs:
        assert run.termination == f"interrupted: {signame}"
        assert run.summary["exit"][0] == "torque off"
        assert_log_complete(run)
    report = json.loads((root / "report.json").read_text())
    assert [r["termination"] for r in report["runs"]] == [f"interrupted: {signame}"] * 2


def test_workers_are_for_a_comparison(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    assert main(["run", "impact", "--workers", "2", "--out", str(tmp_path)]) == 2
    assert "--workers applies to the comparison" in capsys.readouterr().err
    assert main(["run", "--workers", "0", "--out", str(tmp_path)]) == 2
    assert not list(tmp_path.iterdir())  # refused before any run directory
