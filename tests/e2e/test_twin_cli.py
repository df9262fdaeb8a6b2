"""`hil twin` end to end: a twin's file runs as it is through the emulated buses, and
`hil twin --check` replays that run on it.

The twin here is written from the bench's truth (tests/support/bench_hardware.py), as a fitted
twin is written (hil/twin/figures.py twin_config, hil/twin/toml_file.py): `hil run impact
--config twin.toml --emulate` runs it in an embedded `hil emulate` behind the pseudo-terminals.
`hil twin --check` replays that run in process on the twin and on the default emulator: the
twin's closed-loop replay gives the run back (a lock-step run in process logs the bytes it
logs through the buses) and its open-loop replay within the log's rounding. Bad input: exit 2;
a log too short to fit: exit 1 and no file.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from hil.config import load_config
from hil.twin.figures import figures_of, twin_config
from hil.twin.toml_file import write_config
from sim_backend.friction import GearboxFriction
from tests.support.bench_hardware import truth_config

pytestmark = pytest.mark.slow


def _hil(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "hil", *args], capture_output=True, text=True, timeout=240
    )


def test_twin_file_runs_and_checks(tmp_path: Path) -> None:
    host = load_config()
    twin = twin_config(host, figures_of(truth_config(host)), GearboxFriction.LOAD_DEPENDENT)
    path = write_config(twin, tmp_path / "twin.toml", ["a twin for the test"])
    run = _hil(
        "run", "impact", "--config", str(path), "--emulate", "--controller", "gc+lqr+dob",
        "--out", str(tmp_path / "runs"), "--no-plots", "--no-mcap", "--duration", "2",
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    (run_dir,) = (tmp_path / "runs").iterdir()
    meta = json.loads((run_dir / "meta.json").read_text())
    assert meta["config"]["emulator"]["plant"]["gearbox_friction_model"] == "load-dependent"
    check = _hil("twin", "--check", str(path), str(run_dir), "--out", str(tmp_path / "check"))
    assert check.returncode == 0, check.stderr
    residuals = json.loads((tmp_path / "check" / "check.json").read_text())["residuals"]

    def mae(loop: str, emulator: str) -> float:
        (value,) = [
            r["mae"]
            for r in residuals
            if r["loop"] == loop and r["emulator"] == emulator and r["signal"] == "link_angle_rad"
        ]
        return value

    assert mae("closed loop", "twin") == 0.0
    assert mae("open loop", "twin") < 1e-6  # mrad: the log's 9 decimals
    # the run's own configuration is the twin: its "default" emulator is the twin too
    assert mae("closed loop", "default") == 0.0
    assert (tmp_path / "check" / "report.md").is_file()
    assert (tmp_path / "check" / f"{run_dir.name}.png").is_file()
    # an impact run alone is no identification: too short a fit window, said, nothing written
    fit = _hil("twin", str(run_dir), "--out", str(tmp_path / "fitted.toml"))
    assert fit.returncode == 1, fit.stderr
    assert "CANNOT BE TRUSTED" in fit.stderr and "samples" in fit.stderr
    assert not (tmp_path / "fitted.toml").exists()


def test_bad_input_exits_2(tmp_path: Path) -> None:
    result = _hil("twin", str(tmp_path))
    assert result.returncode == 2
    assert "not a run directory" in result.stderr
