"""examples/load_and_compare.py runs as its docstring says: two runs on the emulated testbed,
loaded, a figure of its own, and `hil compare` on them (with pandas and without)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "load_and_compare.py"


def _run(out: Path, *, pandas: bool) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "HIL_EXAMPLE_OUT": str(out)}
    command = [sys.executable, str(EXAMPLE)]
    if not pandas:  # the same script where `import pandas` fails, as without the extra
        command = [sys.executable, "-c", _WITHOUT_PANDAS, str(EXAMPLE)]
    return subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=300, env=env)


_WITHOUT_PANDAS = (
    "import runpy, sys; sys.modules['pandas'] = None; "
    "sys.argv = sys.argv[1:]; runpy.run_path(sys.argv[0], run_name='__main__')"
)


@pytest.mark.parametrize("pandas", [True, False], ids=["with-pandas", "without-pandas"])
def test_the_load_and_compare_example_runs(tmp_path: Path, pandas: bool) -> None:
    if pandas:
        pytest.importorskip("pandas")
    done = _run(tmp_path, pandas=pandas)
    assert done.returncode == 0, done.stderr
    out = done.stdout
    assert "pid: safety stop: current (back_off); contact force peak" in out
    assert "gc+lqr+dob (Kdist 1): completed; contact force peak" in out
    if pandas:
        assert "largest |motor current| by phase [A]" in out and "experiment" in out
    else:
        assert "(without pandas: Table.to_pandas() needs pandas" in out
    assert (tmp_path / "contact_force.png").stat().st_size > 10_000
    assert "hil compare: 2 runs of contact" in out
    report = (tmp_path / "compare" / "report.md").read_text()
    assert "| 1 | pid |" in report and "![signals](signals.png)" in report
