"""`hil sweep` as a user runs it: Ctrl-C in the middle (SIGINT to its whole process group, as
a terminal sends it) or SIGTERM to it (as a job scheduler stops it), then the same command
again: every finished run is kept, none is run twice, the rest are run, the summary of the
interrupted sweep is written, and no Ray process is left behind.

The signal comes at a known point, not after a guess at how long the runs take (a fast
machine once finished all six before it arrived): the sweep runs through a wrapper that
sends it right after the second row is written (`Progress.tick`, called once per row)."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("ray")

# `python -c WRAPPER SIGNAL ARGS...`: `hil ARGS...`, signalled after its second row.
WRAPPER = """
import os, signal, sys
import hil.sweep.engine as engine
from hil.cli import main
signum = getattr(signal, sys.argv[1])
# as from a terminal: a process started in the background by a non-interactive shell (a CI
# script's `cmd &`) inherits SIGINT ignored, and Python then keeps it ignored
signal.signal(signal.SIGINT, signal.default_int_handler)
tick = engine.Progress.tick
def tick_then_signal(self, row, values):
    tick(self, row, values)
    if self.done == 2:
        if signum == signal.SIGINT:
            os.killpg(os.getpgid(0), signum)  # a terminal's Ctrl-C: the whole group
        else:
            os.kill(os.getpid(), signum)
engine.Progress.tick = tick_then_signal
sys.exit(main(sys.argv[2:]))
"""
SPEC = """
title = "interrupt"
experiments = ["impact"]
controllers = ["pid"]
duration_s = 2.0
[sampling]
method = "grid"
[[parameter]]
name = "Kp"
targets = ["emulator.servo.position_gain_per_s"]
values = [8.0, 9.0, 10.0, 11.0, 12.0, 13.0]
"""


def _rows(out: Path) -> list[dict[str, str]]:
    path = out / "results.csv"
    if not path.is_file():
        return []
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _ray_processes() -> set[str]:
    """pid and command of every Ray process running on the machine (raylet, GCS, workers). A
    zombie (`<defunct>`) has ended: only its exit status waits for a parent that may never
    reap it."""
    ps = subprocess.run(["ps", "-eo", "pid,args"], capture_output=True, text=True).stdout
    markers = ("raylet", "gcs_server", "ray::", "default_worker.py")
    return {
        line.strip()
        for line in ps.splitlines()
        if any(m in line for m in markers) and "<defunct>" not in line
    }


def _new_ray_processes(before: set[str]) -> set[str]:
    """Ray processes started since `before` still running after a grace period (Ray's agents
    notice their raylet's end by polling: measured up to ~30 s on a loaded 2-core machine)."""
    deadline = time.monotonic() + 60
    while (left := _ray_processes() - before) and time.monotonic() < deadline:
        time.sleep(0.5)
    return left


@pytest.mark.slow
@pytest.mark.ray
@pytest.mark.timeout(600)
@pytest.mark.parametrize("signame", ["SIGINT", "SIGTERM"])
def test_a_stopped_sweep_then_the_same_command_resumes_without_repeating(
    tmp_path: Path, signame: str
) -> None:
    spec, out = tmp_path / "interrupt.toml", tmp_path / "out"
    spec.write_text(SPEC)
    args = ["sweep", str(spec), "--workers", "1", "--out", str(out)]
    ray_before = _ray_processes()
    process = subprocess.Popen(
        [sys.executable, "-c", WRAPPER, signame, *args],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
    )  # fmt: skip
    _, err = process.communicate(timeout=300)
    assert process.returncode == 1, err
    before = _rows(out)
    assert len(before) == 2, err  # the rows written before the signal, no more, no fewer
    assert "Traceback" not in err, err
    summary = json.loads((out / "summary.json").read_text())
    assert (summary["interrupted"], summary["finished"], summary["runs"]) == (True, 2, 6)
    assert not _new_ray_processes(ray_before)  # the interrupted sweep shut Ray down
    command = [sys.executable, "-m", "hil", *args]

    again = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stderr
    after = _rows(out)
    assert after[: len(before)] == before  # kept as they were
    assert len(after) == 6 and len({r["run_id"] for r in after}) == 6  # none twice, none lost
    assert f"{len(before)} done before, {6 - len(before)} to run" in again.stderr
    assert all(r["ending"] == "completed" for r in after)
    assert not _new_ray_processes(ray_before)
