"""The run log's own process (hil/output/log_process.py): the same files, byte for byte, as a
log written in the loop's process; and nothing lost when either process ends unexpectedly - a
loop killed outright leaves every row it handed over and a finished run.mcap, a writer killed
mid-run stops the run like a lost bus (torque off, summary written)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader

import hil.loop.runner
from hil.config import load_config
from hil.experiments import IMPACT
from hil.output.log_process import LogProcess
from hil.output.rundir import load_run
from hil.output.runlog import RunLog
from hil.vocabulary import Termination
from tests.support.rig import assert_log_complete, run_in_process

CONFIG = load_config()


def test_the_writers_process_writes_the_same_files_as_the_loops_own(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    result, run = run_in_process(CONFIG, IMPACT, "gc+lqr+dob", tmp_path / "process", duration_s=1)
    assert result.ok
    assert_log_complete(run)
    in_loop = RunLog
    monkeypatch.setattr(
        hil.loop.runner,
        "open_run_log",
        lambda *args, mcap, sinks, term_columns, **_: in_loop(
            *args, mcap=mcap, sinks=sinks, term_columns=term_columns
        ),
    )
    result, same = run_in_process(CONFIG, IMPACT, "gc+lqr+dob", tmp_path / "loop", duration_s=1)
    assert result.ok
    for name in ("log.csv", "events.jsonl"):
        assert (run.dir / name).read_bytes() == (same.dir / name).read_bytes(), name
    timing = [(run.dir / "timing.csv").read_text(), (same.dir / "timing.csv").read_text()]
    rows = len((run.dir / "log.csv").read_text().splitlines())
    assert [len(text.splitlines()) for text in timing] == [rows] * 2


def test_a_writer_killed_mid_run_stops_it_like_a_lost_bus_and_the_loop_writes_the_rest(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Issue 25: after a writer SIGKILL, events.jsonl lacked the exit's torque off and summary
    `ticks` disagreed with the rows (those the writer had not written yet were lost). The
    writer is killed while it trails the loop (not waited for): every row and event it had
    not written is written by the loop."""
    real_cycle = hil.loop.runner.Loop._cycle

    def cycle(self, tick):
        if tick.index == 100:
            assert isinstance(self.log, LogProcess)
            os.kill(self.log.pid, signal.SIGKILL)
            time.sleep(0.2)
        real_cycle(self, tick)

    monkeypatch.setattr(hil.loop.runner.Loop, "_cycle", cycle)
    result, run = run_in_process(CONFIG, IMPACT, "pid", tmp_path, duration_s=2)
    assert result.termination is Termination.BUS_FAILURE
    assert "log writer process" in result.ending.text and "ended" in result.ending.text
    assert run.summary["termination"] == result.ending.text  # written by the loop's process
    assert run.events[-1]["kind"] == "torque_off", run.events[-1]
    assert run.events[-1]["message"] == "exit: torque off"
    assert_log_complete(run)  # every row, none torn, as many as summary.json's ticks
    assert run.summary["ticks"] == 101 and list(run.columns["tick"]) == list(range(101))
    kinds = [e["kind"] for e in run.events]
    assert kinds[-3:] == ["log_writer_lost", "bus_failure", "torque_off"], kinds
    assert result.exit_notes[0] == "torque off"
    assert "the loop wrote the rest" in result.exit_notes[1]
    record = run.summary["record"]
    assert record["state"] == "written by the loop" and record["rows"] == 101
    assert record["rows_by_writer"] + record["rows_by_loop"] == 101
    assert record["writer"]["kind"] == "log_writer_lost" and record["writer"]["tick"] == 100
    timing = (run.dir / "timing.csv").read_text().splitlines()
    assert len(timing) == 102 and timing[-1].startswith("100,")


_KILLED_LOOP = textwrap.dedent(
    """
    import os, sys
    from pathlib import Path
    import hil.loop.run_record
    from hil.config import load_config
    from hil.experiments import IMPACT
    from tests.support.rig import run_in_process

    handed = os.open(sys.argv[2], os.O_WRONLY | os.O_CREAT | os.O_APPEND)
    real = hil.loop.run_record.RunRecord.write_kept

    def write(self):
        kept = self._kept
        seconds = real(self)
        if kept is not None:  # this tick's rows are the writer's now
            os.write(handed, b"%d\\n" % kept[0][0])
        return seconds

    hil.loop.run_record.RunRecord.write_kept = write
    run_in_process(load_config(), IMPACT, "pid", Path(sys.argv[1]), duration_s=60)
    """
)


def test_a_loop_killed_outright_loses_no_row_it_handed_over(tmp_path: Path) -> None:
    handed = tmp_path / "handed.txt"
    out = tmp_path / "run"
    loop = subprocess.Popen(
        [sys.executable, "-c", _KILLED_LOOP, str(out), str(handed)],
        cwd=Path(__file__).resolve().parents[2],
    )
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and len(_lines(handed)) < 300:
            time.sleep(0.05)
        os.kill(loop.pid, signal.SIGKILL)
    finally:
        loop.wait(timeout=30)
    assert len(_lines(handed)) >= 300
    mcap_file = out / "run.mcap"
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and not _mcap_finished(mcap_file):
        time.sleep(0.1)  # the writer writes what it holds, then finishes run.mcap
    last = int(_lines(handed)[-1])
    run = load_run(out)
    logged = [int(tick) for tick in run.columns["tick"]]
    assert logged[-1] >= last and logged == list(range(len(logged)))
    assert (out / "log.csv").read_text().endswith("\n")
    with open(mcap_file, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None  # the index was written: a finished file
        joints = [m for _, channel, m in reader.iter_messages() if channel.topic == "/joints"]
    assert json.loads(joints[-1].data)["tick"] == logged[-1]


def _lines(path: Path) -> list[str]:
    return path.read_text().splitlines() if path.exists() else []


def _mcap_finished(path: Path) -> bool:
    """An MCAP file ends with its magic once its writer finished it."""
    return path.exists() and path.read_bytes()[-8:] == b"\x89MCAP0\r\n"
