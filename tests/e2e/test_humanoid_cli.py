"""`hil run stand|push` on DYROS-JET's emulated legs, through the buses a real robot has: the
twelve actuators on an emulated Dynamixel chain (ROBOTIS's SDK on a pty), the twelve link
encoders and the two foot force/torque sensors on emulated CAN (python-can's slcan on a pty)."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import pytest

from controller.humanoid import LEG_JOINT_NAMES
from drivers.joint_bus import wrench_keys
from hil.cli import main
from tests.support.rig import assert_log_complete, load_run

pytestmark = pytest.mark.slow


def test_stand_runs_through_the_emulated_buses(tmp_path: Path) -> None:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(
            ["run", "stand", "--controller", "gc", "--duration", "1.5", "--json"]
            + ["--out", str(tmp_path)]
        )
    assert code == 0, out.getvalue()
    metrics = json.loads(out.getvalue().strip().splitlines()[-1])
    for key in ("pelvis_tilt_rad", "max_deflection_rad", "zmp_max_error_m", "fell"):
        assert key in metrics, key
    assert metrics["fell"] is False
    (run_dir,) = tmp_path.iterdir()
    run = load_run(run_dir, code)
    assert_log_complete(run)
    columns = run.columns
    for joint in LEG_JOINT_NAMES:
        assert f"link_angle_rad[{joint}]" in columns
    for foot in ("left_foot", "right_foot"):
        for key in wrench_keys(foot):
            assert key in columns
    # the feet carry the robot's weight (49.96 kg) once it settled on its springs
    late = run.data.time_s > run.data.time_s[-1] - 0.3
    vertical = columns["left_foot_fz_n"][late] + columns["right_foot_fz_n"][late]
    assert abs(vertical.mean() - 49.96 * 9.81) < 0.05 * 49.96 * 9.81
    assert list(run_dir.glob("*.png")), "no plot written"


def test_an_experiment_refuses_another_robots_configuration(tmp_path: Path, capsys) -> None:
    code = main(["run", "contact", "--robot", "dyros-jet", "--out", str(tmp_path)])
    assert code == 2
    assert "is for the robot 'testbed'" in capsys.readouterr().err
    config = tmp_path / "testbed.toml"
    with contextlib.redirect_stdout(io.StringIO()) as text:
        main(["config"])
    config.write_text(text.getvalue())
    code = main(["run", "stand", "--config", str(config), "--emulate", "--out", str(tmp_path)])
    assert code == 2
    assert "is for the robot 'dyros-jet'" in capsys.readouterr().err
    assert not list(tmp_path.glob("*/log.csv"))


def test_the_lqr_stands_the_robot_through_the_emulated_buses(tmp_path: Path) -> None:
    """The configuration's LQR (the closed chain on the servo cascade) with the DOB at the
    lab's Kdist: no safety stop, the pelvis upright, the ZMP in the middle of the feet, and the
    gain rescheduled off the tick (docs/humanoid.md)."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(
            ["run", "stand", "--robot", "dyros-jet", "--controller", "gc+lqr+dob"]
            + ["--kdist", "0.2", "--duration", "3", "--json", "--no-plots", "--no-mcap"]
            + ["--out", str(tmp_path)]
        )
    assert code == 0, out.getvalue()
    metrics = json.loads(out.getvalue().strip().splitlines()[-1])
    assert metrics["termination"] == "completed"
    assert metrics["fell"] is False
    assert metrics["pelvis_tilt_rad"] < 0.03
    assert metrics["zmp_max_error_m"] < 0.03
    (run_dir,) = tmp_path.iterdir()
    run = load_run(run_dir, code)
    assert_log_complete(run)
    assert not run.trips()
    assert run.summary["gain_schedule"]["designs"] >= 25  # every 0.1 s
