"""The run's record when the disk refuses a write (issue 25): log.csv ended mid-row, the
metrics' reader died of an IndexError (no summary.json, no --json line, no word of a full
disk), `hil identify` on the torn log likewise, and the room check said "0.0 GB". Now a line is
written whole or not at all, the run stops in a defined state (torque off) saying which file
could not be written and why, summary.json still goes in (the room kept for it), a torn log is
read without its torn row and says so, and the room check speaks in kB/MB/GB.

A real full disk (a small tmpfs) is tests/e2e/test_full_disk.py; here the same refusal comes
from a file-size limit (RLIMIT_FSIZE: a write past it fails, EFBIG), which needs no root."""

from __future__ import annotations

import json
import os
import resource
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from hil.cli import main
from hil.config import load_config
from hil.output.record_files import RecordFile, RecordWriteError
from hil.output.rundir import describe_bytes, estimated_record_bytes, load_run
from hil.output.runlog import read_log_checked

REPO = Path(__file__).resolve().parents[2]


def _limited(limit_bytes: int, work) -> int:
    """`work()` in a forked child whose files may not grow past `limit_bytes`; its exit code."""
    pid = os.fork()
    if pid == 0:
        code = 1
        try:
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a refused write fails, EFBIG
            resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, resource.RLIM_INFINITY))
            code = work()
        finally:
            os._exit(code)
    return os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1])


def test_a_line_the_disk_refuses_is_cut_off_again(tmp_path: Path) -> None:
    path = tmp_path / "log.csv"
    line = "0123456789," * 9 + "\n"  # 100 bytes

    def work() -> int:
        record = RecordFile(path)
        for number in range(100):
            try:
                record.write(line)
            except RecordWriteError as exc:
                assert str(path) in str(exc) and "too large" in str(exc), str(exc)
                return 10 + number
        return 0

    code = _limited(1050, work)  # the 11th line is refused after 50 of its bytes
    assert code == 20, code
    assert path.read_text() == line * 10  # no half line


def test_a_torn_last_row_is_read_around_and_said(tmp_path: Path) -> None:
    log = tmp_path / "log.csv"
    log.write_text("tick,time_s,x\n0,0.0,1.5\n1,0.005,2.5\n2,0.01,3")
    columns, note = read_log_checked(log)
    assert list(columns["tick"]) == [0.0, 1.0] and note is not None and "torn" in note
    (tmp_path / "events.jsonl").write_text('{"kind": "open"}\n{"kind": "tor')
    run = load_run(tmp_path)
    assert [e["kind"] for e in run.events] == ["open"]
    assert len(run.notes) == 2 and all(str(tmp_path) in note for note in run.notes)
    log.write_text("tick,time_s,x\n0,0.0,1.5\n1,0.005\n2,0.01,3.0\n")
    with pytest.raises(ValueError, match="line 3 has 2 cells"):
        read_log_checked(log)


_RUN = textwrap.dedent(
    """
    import resource, signal, sys
    from pathlib import Path
    import hil.loop.runner
    from hil.config import load_config
    from hil.experiments import IMPACT
    from hil.output.runlog import RunLog
    from tests.support.rig import run_in_process

    if sys.argv[2] == "loop":  # the log in the loop's process (as with the live view)
        hil.loop.runner.open_run_log = lambda *a, mcap, sinks, term_columns, **_: RunLog(
            *a, mcap=mcap, sinks=sinks, term_columns=term_columns
        )
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (40_000, resource.RLIM_INFINITY))
    result, run = run_in_process(load_config(), IMPACT, "pid", Path(sys.argv[1]), duration_s=9,
                                 mcap=False)
    print(result.termination, "|", result.ending.text)
    print("|".join(result.exit_notes))
    """
)


@pytest.mark.faults
@pytest.mark.parametrize("writer", ["process", "loop"])
def test_a_run_whose_record_is_refused_stops_and_says_so(tmp_path: Path, writer: str) -> None:
    out = tmp_path / "run"
    run = subprocess.run(
        [sys.executable, "-c", _RUN, str(out), writer],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stderr
    ending, notes = run.stdout.strip().splitlines()[-2:]
    assert ending.startswith("bus failure |"), ending
    assert f"cannot write {out / 'log.csv'}: file too large" in ending
    assert "record incomplete" in notes and "not written" in notes
    data = load_run(out)  # no torn row, nothing to read around
    assert data.notes == ()
    text = (out / "log.csv").read_text()
    assert text.endswith("\n") and 200 < len(text.splitlines()) < 1800
    summary = data.summary  # written all the same (summary.json has a file of its own)
    assert summary["termination"].startswith("bus failure")
    assert summary["record"]["state"] == "incomplete"
    assert summary["metrics"] and "error" not in summary["metrics"]
    assert data.events[-1]["message"] == "exit: torque off"
    assert summary["exit"][0] == "torque off"
    assert not (out / ".record-reserve").exists()


def test_the_room_check_speaks_in_units_that_fit(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    assert describe_bytes(950) == "950 B"
    assert describe_bytes(12_345) == "12.3 kB"
    assert describe_bytes(2_097_152) == "2.1 MB"
    assert describe_bytes(19.2e9) == "19.2 GB"
    usage = type("Usage", (), {"free": 1_500_000, "total": 2_097_152, "used": 597_152})
    monkeypatch.setattr("hil.cli.run.shutil.disk_usage", lambda _: usage)
    assert main(["run", "impact", "--out", str(tmp_path), "--duration", "60"]) == 2
    err = capsys.readouterr().err
    config = load_config()
    ticks = 60 * int(config.loop.rate_hz) + config.loop.stop_cycles
    need = describe_bytes(estimated_record_bytes(ticks, 1, mcap=True))  # ~15 MB
    assert "more than the 1.5 MB free there" in err and f"takes about {need}" in err, err
    assert need.endswith(" MB")
    assert "0.0 GB" not in err


def test_meta_and_summary_are_whole_or_not_there(tmp_path: Path) -> None:
    """A JSON file the disk refuses leaves nothing half-written behind."""
    from hil.output.runlog import write_summary_file

    def work() -> int:
        try:
            write_summary_file(tmp_path, {"big": "x" * 10_000})
        except RecordWriteError as exc:
            return 3 if "summary.json" in str(exc) else 4
        return 0

    assert _limited(5_000, work) == 3
    assert sorted(os.listdir(tmp_path)) == []
    write_summary_file(tmp_path, {"small": 1})
    assert json.loads((tmp_path / "summary.json").read_text()) == {"small": 1}
