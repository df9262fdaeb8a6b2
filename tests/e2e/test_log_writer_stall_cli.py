"""The issue's scenario as a user meets it (issue 25): `hil run impact --duration 60`, then
`kill -STOP` the log writer (a hung NFS or USB disk does the same). Before, the loop froze with
torque on once the pipe was full (also with --realtime), Ctrl-C and SIGTERM ignored. Now the
run stops within a second or so as on a lost bus, torque off, and its record - written by the
loop from where the writer stopped - says what stalled and when."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.support.rig import assert_log_complete, load_run

pytestmark = [
    pytest.mark.faults,
    pytest.mark.subprocess,
    pytest.mark.timeout(240),
    pytest.mark.skipif(not Path("/proc/self/fd").exists(), reason="needs Linux's /proc"),
]

REPO = Path(__file__).resolve().parents[2]
NO_HANG_S = 90.0  # a 60 s run with its writer stopped must have ended by then


def _writer_of(root: Path, host: int) -> int | None:
    """The host's child process that holds the run's log.csv open: the log writer."""
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            ppid = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
            if ppid != host:
                continue
            for fd in (entry / "fd").iterdir():
                target = os.readlink(fd)
                if target.startswith(str(root)) and target.endswith("log.csv"):
                    return int(entry.name)
        except (OSError, ValueError, IndexError):
            continue
    return None


@pytest.mark.parametrize("clock", ["lockstep", "realtime"])
def test_hil_run_with_its_writer_stopped_stops_with_torque_off(tmp_path: Path, clock: str) -> None:
    args = ["run", "impact", "--duration", "60", "--json", "--no-plots", "--out", str(tmp_path)]
    if clock == "realtime":
        args.append("--realtime")
    host = subprocess.Popen(
        [sys.executable, "-m", "hil", *args],
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    writer = None
    try:
        deadline = time.monotonic() + 60
        while writer is None and time.monotonic() < deadline and host.poll() is None:
            logs = list(tmp_path.glob("*/log.csv"))
            if logs and logs[0].stat().st_size > 20_000:  # ~100 ticks in
                writer = _writer_of(tmp_path, host.pid)
            time.sleep(0.01)
        assert writer is not None, "no log writer found"
        os.kill(writer, signal.SIGSTOP)
        stopped = time.monotonic()
        out, err = host.communicate(timeout=NO_HANG_S)
        ended_after_s = time.monotonic() - stopped
    finally:
        if host.poll() is None:  # it hung: nothing left behind
            with contextlib.suppress(ProcessLookupError):
                os.killpg(host.pid, signal.SIGKILL)
            host.wait()
        if writer is not None:
            with contextlib.suppress(ProcessLookupError):
                os.kill(writer, signal.SIGKILL)
    assert host.returncode == 1, out + err
    record = json.loads(out.strip().splitlines()[-1])
    assert "has stalled" in record["termination"] and "stopped" in record["termination"]
    assert record["exit"][0] == "torque off"
    assert ended_after_s < 30, ended_after_s  # the stall is found in ~0.6 s; the rest: load
    (out_dir,) = tmp_path.iterdir()
    run = load_run(out_dir)
    assert_log_complete(run)
    assert run.summary["record"]["state"] == "written by the loop"
    (stall,) = run.events_of("log_writer_stalled")
    assert stall["tick"] < 12000
    assert run.events[-1]["message"] == "exit: torque off"
