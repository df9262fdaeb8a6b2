"""Every example in examples/ runs, as its docstring says, so that none can rot: the plug-ins
through `hil run` on the emulated robots (the embedded emulator, lock-step), the Python ones as
scripts."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
PD = "examples/pd_gravity.py:PdGravity"


def _hil(*args: str, out: Path) -> tuple[int, Path]:
    """`hil run ...` as a user types it, from the repository's root; the run's directory."""
    command = [sys.executable, "-m", "hil", "run", *args, "--out", str(out), "--no-plots"]
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=300)
    runs = sorted(out.iterdir()) if out.exists() else []
    assert len(runs) == 1, done.stderr
    return done.returncode, runs[0]


def _summary(run: Path) -> dict:
    return json.loads((run / "summary.json").read_text())


@pytest.mark.parametrize("experiment", ["contact", "impact"])
def test_the_pd_example_runs_on_the_testbed(experiment: str, tmp_path: Path) -> None:
    code, run = _hil(experiment, "--controller", PD, out=tmp_path)
    summary = _summary(run)
    meta = json.loads((run / "meta.json").read_text())
    assert meta["controller"] == "PdGravity" and run.name.endswith(f"{experiment}-pd-gravity")
    header = (run / "log.csv").read_text().splitlines()[0]
    assert "feedforward_rad" in header and "feedback_rad" in header
    if experiment == "impact":
        assert code == 0 and summary["termination"] == "completed"
    else:  # driven into the block, its stiff PD backs off on the current guard
        assert summary["ticks"] > 1500 and summary["exit"] == ["torque off"]


def test_the_pd_example_runs_on_the_humanoid_stand(tmp_path: Path) -> None:
    code, run = _hil("stand", "--controller", PD, "--duration", "3", out=tmp_path)
    summary = _summary(run)
    assert code == 0 and summary["termination"] == "completed", summary["termination"]
    assert summary["metrics"]["fell"] is False


@pytest.mark.parametrize("fault", ["nan", "raise"])
def test_the_misbehaving_example_is_stopped_with_torque_off(fault: str, tmp_path: Path) -> None:
    spec = "examples/misbehaving_controller.py:Misbehaving"
    code, run = _hil("contact", "--controller", spec, "--param", f"fault={fault}", out=tmp_path)
    summary = _summary(run)
    assert code == 1
    assert summary["termination"] == "safety stop: controller_fault (torque_off)"
    (event,) = [e for e in summary["safety_events"] if e["cause"] == "controller_fault"]
    assert event["action"] == "torque_off" and event["time_s"] == pytest.approx(1.0, abs=0.01)
    events = [json.loads(line) for line in (run / "events.jsonl").read_text().splitlines()]
    off = [e for e in events if e["kind"] == "torque_off"]
    assert off and off[0]["time_s"] <= event["time_s"] + 0.011


def test_the_experiment_example_runs(tmp_path: Path) -> None:
    spec = "examples/sine_experiment.py:Sine"
    code, run = _hil(spec, "--controller", PD, out=tmp_path)
    metrics = _summary(run)["metrics"]
    assert code == 0 and run.name.endswith("-sine-pd-gravity")
    assert 0 < metrics["rms_error_rad"] < metrics["max_error_rad"] < 0.2


def _script(name: str, tmp_path: Path, *args: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "HIL_EXAMPLE_OUT": str(tmp_path)}
    return subprocess.run(
        [sys.executable, str(EXAMPLES / name), *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        env=env,
    )


def test_every_example_is_tested() -> None:
    tested = "".join(test.read_text() for test in Path(__file__).parent.glob("test_*.py"))
    for example in EXAMPLES.glob("*.py"):
        assert example.name in tested, f"examples/{example.name} is not run by any test"


def test_the_raw_loop_example_runs(tmp_path: Path) -> None:
    done = _script("sine_loop.py", tmp_path)
    assert done.returncode == 0, done.stderr
    (run,) = tmp_path.iterdir()
    summary = _summary(run)
    assert summary["termination"] == "completed" and summary["exit"] == ["torque off"]
    assert summary["ticks"] == 5 + 800 + 5  # the hold, 4 s of yours, the stop cycles


def test_the_python_pd_example_runs(tmp_path: Path) -> None:
    done = _script("pd_gravity_python.py", tmp_path)
    assert done.returncode == 0, done.stderr
    assert "impact: completed" in done.stdout and "fell = False" in done.stdout
    assert len(list(tmp_path.iterdir())) == 3
