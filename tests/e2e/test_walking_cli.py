"""`hil run walk-slow` through the emulated buses, and what `hil run walking` refuses."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import pytest

from hil.cli import main
from tests.support.rig import assert_log_complete, load_run


@pytest.mark.slow
def test_walk_slow_runs_through_the_emulated_buses(tmp_path: Path) -> None:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(
            ["run", "walk-slow", "--controller", "gc", "--duration", "2.5", "--json"]
            + ["--no-plots", "--out", str(tmp_path)]
        )
    assert code == 0, out.getvalue()
    metrics = json.loads(out.getvalue().strip().splitlines()[-1])
    for key in ("zmp_rms_error_lateral_m", "zmp_max_error_sagittal_m", "zmp_at_edge_s"):
        assert key in metrics, key
    assert metrics["steps_completed"] == 0 and metrics["fell"] is False  # 2.5 s: no step yet
    (run_dir,) = tmp_path.iterdir()
    run = load_run(run_dir, code)
    assert_log_complete(run)
    assert run.summary["experiment"] == "walk-slow"


def test_the_walking_comparison_takes_no_single_run_options(tmp_path: Path, capsys) -> None:
    code = main(["run", "walking", "--controller", "gc", "--out", str(tmp_path)])
    assert code == 2
    assert "--controller" in capsys.readouterr().err
    code = main(["run", "walking", "--robot", "testbed", "--out", str(tmp_path)])
    assert code == 2
    assert "dyros-jet" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())
