"""A disk that fills up during a run (issue 25), as a user meets it: `hil run` into a small
tmpfs that another process fills. Before, log.csv ended mid-row and the metrics' reader died of
an IndexError - no summary.json, no --json line, no word that the disk was full - and a
comparison wrote no report at all. Now the run stops with torque off and says, in one line,
which file could not be written and why; every row written stays whole; summary.json and the
--json line are still there; a comparison still prints its report and says why report.md is
not on disk.

Mounting a tmpfs needs root (CAP_SYS_ADMIN): elsewhere these tests are skipped, and
tests/hil/test_record_on_a_full_disk.py makes the same refusal with a file-size limit."""

from __future__ import annotations

import contextlib
import json
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from hil.output.rundir import load_run

pytestmark = [pytest.mark.faults, pytest.mark.subprocess, pytest.mark.timeout(300)]

SIZE = "4m"


@pytest.fixture
def small_disk(tmp_path: Path) -> Iterator[Path]:
    mount = tmp_path / "disk"
    mount.mkdir()
    made = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", f"size={SIZE}", "tmpfs", str(mount)],
        capture_output=True,
        text=True,
    )
    if made.returncode != 0:
        pytest.skip(f"cannot mount a {SIZE} tmpfs here (needs root): {made.stderr.strip()}")
    try:
        yield mount
    finally:
        subprocess.run(["umount", "-l", str(mount)], check=False)


class _Filler(threading.Thread):
    """Fills the disk once the first run's log.csv has `rows` rows."""

    def __init__(self, disk: Path, rows: int = 200) -> None:
        super().__init__(daemon=True)
        self.disk = disk
        self.rows = rows
        self.filled = threading.Event()
        self.done = False

    def run(self) -> None:
        deadline = time.monotonic() + 120
        while not self.done and time.monotonic() < deadline:
            logs = list(self.disk.rglob("log.csv"))
            if logs and _lines(logs[0]) > self.rows:
                break
            time.sleep(0.005)
        with contextlib.suppress(OSError), open(self.disk / "filler", "wb", buffering=0) as f:
            while True:
                f.write(b"x" * 65536)
        with contextlib.suppress(OSError), open(self.disk / "filler", "ab", buffering=0) as f:
            while True:  # the last few blocks
                f.write(b"x" * 512)
        self.filled.set()


def _lines(path: Path) -> int:
    try:
        return path.read_bytes().count(b"\n")
    except OSError:
        return 0


def _hil(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "hil", *args], capture_output=True, text=True, timeout=240
    )


def test_a_run_on_a_disk_that_fills_up_stops_and_says_so(small_disk: Path) -> None:
    filler = _Filler(small_disk)
    filler.start()
    run = _hil("run", "impact", "--duration", "9", "--json", "--no-plots", "--out", str(small_disk))
    filler.done = True
    filler.join()
    assert filler.filled.is_set(), "the disk was not filled during the run"
    assert run.returncode == 1, run.stdout + run.stderr
    (out_dir,) = (p for p in small_disk.iterdir() if p.is_dir())
    said = [line for line in run.stdout.splitlines() if "no space left on device" in line]
    assert said and str(out_dir) in said[0], run.stdout  # which file, and why, in one line
    record = json.loads(run.stdout.strip().splitlines()[-1])  # the --json line
    assert record["termination"].startswith("bus failure: the run's record cannot be written")
    assert record["exit"][0] == "torque off" and "record incomplete" in record["exit"][1]
    data = load_run(out_dir)
    assert data.notes == ()  # no torn row or line to read around
    text = (out_dir / "log.csv").read_text()
    assert text.endswith("\n") and len(text.splitlines()) > 200
    assert data.summary["termination"] == record["termination"]
    assert data.summary["record"]["state"] == "incomplete"
    assert data.events[-1]["message"] == "exit: torque off"


def test_a_comparison_on_a_disk_that_fills_up_still_reports(small_disk: Path) -> None:
    filler = _Filler(small_disk)
    filler.start()
    run = _hil("run", "--no-plots", "--json", "--workers", "1", "--out", str(small_disk))
    filler.done = True
    filler.join()
    assert run.returncode == 1, run.stdout + run.stderr
    lines = run.stdout.splitlines()
    (where,) = [line for line in lines if line.startswith("report not written: ")]
    assert "report.md: no space left on device" in where, where
    (report,) = [json.loads(line) for line in lines if line.startswith('{"setup"')]
    assert report["report"] is None and len(report["runs"]) == 16
    first = report["runs"][0]
    assert "no space left on device" in first["termination"], first
    assert any(line.startswith("comparison incomplete: ") for line in lines)
