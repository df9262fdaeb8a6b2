"""Two runs into the same `--out` at the same time each get a directory of their own, created
exclusively (never reused), whatever the clock says.

Both `hil run` processes are held at a gate after start-up and released together, with the
clock that names run directories fixed to one second (the wrapper below patches the
timestamp: the worst case, two runs started within the same second, made certain)."""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from tests.support.rig import assert_log_complete, load_run

SAME_SECOND = "20260101-000000"
WRAPPER = f"""
import pathlib, sys, time
import hil.output.rundir as rundir
import hil.session.session as session
fixed = lambda: {SAME_SECOND!r}
rundir.timestamp = fixed
session.timestamp = fixed  # (a name some versions import directly)
from hil.cli import main
gate = pathlib.Path(sys.argv[1])
while not gate.exists():
    time.sleep(0.001)
sys.exit(main(sys.argv[2:]))
"""


@pytest.mark.timeout(180)
def test_two_runs_started_in_the_same_second_never_share_a_directory(tmp_path: Path) -> None:
    out, gate = tmp_path / "runs", tmp_path / "go"
    processes = [
        subprocess.Popen(
            [
                sys.executable,
                "-c",
                WRAPPER,
                str(gate),
                "run",
                "impact",
                "--controller",
                "pid",
                "--duration",
                duration,
                "--seed",
                seed,
                "--no-plots",
                "--out",
                str(out),
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )  # fmt: skip
        for duration, seed in (("1.2", "1"), ("1.0", "2"))
    ]
    time.sleep(3.0)  # both started up and waiting at the gate
    gate.touch()
    results = [p.communicate(timeout=150) for p in processes]
    for process, (_out, err) in zip(processes, results, strict=True):
        assert process.returncode == 0, err
    dirs = sorted(out.iterdir())
    assert len(dirs) == 2, dirs
    assert all(d.name.startswith(SAME_SECOND) for d in dirs)
    seeds = set()
    for run_dir in dirs:
        meta = json.loads((run_dir / "meta.json").read_text())
        run = load_run(run_dir)
        assert_log_complete(run)
        assert run.summary["ticks"] in (round(1.2 / 0.005) + 5, round(1.0 / 0.005) + 5)
        seeds.add(meta["seed"])
    assert seeds == {1, 2}


def test_a_run_directory_is_created_exclusively_by_many_threads_at_once(tmp_path: Path) -> None:
    from hil.output.rundir import create_run_dir

    made: list[Path] = []
    lock = threading.Lock()
    start = threading.Barrier(16)

    def make() -> None:
        start.wait()
        path = create_run_dir(tmp_path, "20260101-000000-impact-pid")
        with lock:
            made.append(path)

    threads = [threading.Thread(target=make) for _ in range(16)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert len(set(made)) == 16 and all(p.is_dir() for p in made)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in made)
