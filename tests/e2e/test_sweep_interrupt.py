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


# `python -c WRAPPER_AT MOMENT SIGNAL ARGS...`: `hil ARGS...`, signalled (as WRAPPER does) at
# MOMENT: "plan" as the plan is checked; "table" when results.csv has been read (what is
# done), before Ray starts; "ray-start" while `ray.init` runs, once its raylet is up (a thread
# watches for it).
WRAPPER_AT = """
import os, signal, sys, threading, time
import ray
import hil.sweep.engine as engine
from hil.cli import main
from hil.sweep.processes import descendants
moment, signum = sys.argv[1], getattr(signal, sys.argv[2])
signal.signal(signal.SIGINT, signal.default_int_handler)  # as from a terminal (see WRAPPER)
def send():
    if signum == signal.SIGINT:
        os.killpg(os.getpgid(0), signum)
    else:
        os.kill(os.getpid(), signum)
if moment == "plan":
    checked_plan = engine.checked_plan
    def signal_then_plan(*args, **kwargs):
        send()
        return checked_plan(*args, **kwargs)
    engine.checked_plan = signal_then_plan
elif moment == "table":
    table_init = engine.ResultsTable.__init__
    def table_then_signal(self, *args, **kwargs):
        table_init(self, *args, **kwargs)
        send()
    engine.ResultsTable.__init__ = table_then_signal
else:
    init = ray.init
    def raylet_up():
        return any(
            b"raylet" in open(f"/proc/{pid}/cmdline", "rb").read()
            for pid, _ in descendants(os.getpid())
        )
    def send_once_raylet_up():
        deadline = time.monotonic() + 120
        while not raylet_up() and time.monotonic() < deadline:
            time.sleep(0.02)
        print("signal sent while Ray starts", file=sys.stderr, flush=True)
        send()
    def init_then_signal(*args, **kwargs):
        threading.Thread(target=send_once_raylet_up, daemon=True).start()
        result = init(*args, **kwargs)
        print("ray.init returned", file=sys.stderr, flush=True)
        return result
    ray.init = init_then_signal
sys.exit(main(sys.argv[3:]))
"""


def _sweep_at(tmp_path: Path, moment: str, signame: str) -> tuple[subprocess.Popen, Path]:
    tmp_path.mkdir(exist_ok=True)
    spec, out = tmp_path / "interrupt.toml", tmp_path / "out"
    spec.write_text(SPEC)
    args = ["sweep", str(spec), "--workers", "1", "--out", str(out)]
    process = subprocess.Popen(
        [sys.executable, "-c", WRAPPER_AT, moment, signame, *args],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
    )  # fmt: skip
    return process, out


def _interrupted_at(tmp_path: Path, moment: str, signame: str) -> tuple[str, str, Path]:
    """(stdout, stderr, out) of a sweep signalled at `moment`, which ended as interrupted."""
    process, out = _sweep_at(tmp_path, moment, signame)
    stdout, err = process.communicate(timeout=300)
    assert process.returncode == 1, err  # an interruption, as elsewhere in the CLI
    assert "Traceback" not in err, err
    return stdout, err, out


def _interrupted_summary(out: Path, signame: str) -> dict:
    summary = json.loads((out / "summary.json").read_text())
    assert (summary["interrupted"], summary["signal"], summary["runs"]) == (True, signame, 6)
    assert summary["finished"] == len(_rows(out)) < 6
    return summary


@pytest.mark.subprocess
@pytest.mark.timeout(240)
@pytest.mark.parametrize("signame", ["SIGINT", "SIGTERM"])
def test_a_signal_before_ray_starts_ends_the_sweep(tmp_path: Path, signame: str) -> None:
    # while the plan is made: it stops, nothing written
    _, err, out = _interrupted_at(tmp_path / "plan", "plan", signame)
    assert f"interrupted ({signame}) while the plan was made: nothing was run" in err, err
    assert not out.exists()
    # after the plan, results.csv read: Ray is not started, the summary is written
    stdout, _, out = _interrupted_at(tmp_path / "table", "table", signame)
    assert _interrupted_summary(out, signame)["finished"] == 0
    assert f"incomplete ({signame}): rerun the same command to resume" in stdout


@pytest.mark.slow
@pytest.mark.ray
@pytest.mark.timeout(600)
@pytest.mark.parametrize("signame", ["SIGINT", "SIGTERM"])
def test_a_signal_while_ray_starts_is_honoured_and_leaves_a_summary(
    tmp_path: Path, signame: str
) -> None:
    ray_before = _ray_processes()
    # exit 1: the SIGINT not dropped, the SIGTERM not Ray's own exit
    _, err, out = _interrupted_at(tmp_path, "ray-start", signame)
    assert "signal sent while Ray starts" in err, err
    _interrupted_summary(out, signame)
    assert not _new_ray_processes(ray_before)


# `python -c HOLDING_WRAPPER GO ARGS...`: `hil ARGS...`, waiting after its first row until the
# file GO exists (so that it is surely still running when a second sweep starts)
HOLDING_WRAPPER = """
import os, sys, time
import hil.sweep.engine as engine
from hil.cli import main
go = sys.argv[1]
tick = engine.Progress.tick
def tick_then_hold(self, row, values):
    tick(self, row, values)
    deadline = time.monotonic() + 240
    while self.done == 1 and not os.path.exists(go) and time.monotonic() < deadline:
        time.sleep(0.05)
engine.Progress.tick = tick_then_hold
sys.exit(main(sys.argv[2:]))
"""


@pytest.mark.slow
@pytest.mark.ray
@pytest.mark.timeout(600)
def test_a_second_sweep_into_the_same_out_is_refused_while_the_first_runs(
    tmp_path: Path,
) -> None:
    spec, out, go = tmp_path / "interrupt.toml", tmp_path / "out", tmp_path / "go"
    spec.write_text(SPEC)
    args = ["sweep", str(spec), "--workers", "1", "--out", str(out)]
    first = subprocess.Popen(
        [sys.executable, "-c", HOLDING_WRAPPER, str(go), *args],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 240
        while not _rows(out) and first.poll() is None and time.monotonic() < deadline:
            time.sleep(0.2)
        assert _rows(out) and first.poll() is None  # the first is running, a row written
        second = subprocess.run(
            [sys.executable, "-m", "hil", *args], capture_output=True, text=True, timeout=240
        )
        go.touch()
        _, first_err = first.communicate(timeout=300)
    finally:
        if first.poll() is None:
            first.kill()
            first.wait()
    assert second.returncode == 2, second.stderr
    assert f"in use by another sweep (pid {first.pid})" in second.stderr
    assert first.returncode == 0, first_err
    rows = _rows(out)
    assert len(rows) == 6 and len({r["run_id"] for r in rows}) == 6  # each row once
