"""A fixed-base robot from its URDF (the two-link example, `hil config --robot fixed-base`) run
through the emulated buses: its actuators on emulated RS-485 chains (ROBOTIS's SDK on ptys),
its link encoders on emulated CAN, in lock-step.

Held at 0 against gravity, each joint sags by what its load deflects it: under `pid` (the
actuators' own position control) between the gear's tau_g / K and the whole joint's
C tau_g = (1/K + 1/(Kpp kv)) tau_g (the servo's velocity integral winds its part out over
Ti = 15 s), with tau_g the controller's model's; the gravity compensator removes most of it.
Split over two chains the same robot writes the same log, byte for byte. Without link encoders
(a stock arm) pid and gc run on the motor encoders, and the LQR is refused before a byte."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import numpy as np
import pytest

from controller import joint_static_compliance
from hil.cli import main
from hil.config import default_config_text, load_config
from hil.robots.fixed_base.model import fixed_base_links

pytestmark = pytest.mark.slow


def hold(tmp_path: Path, *args: str) -> tuple[dict, Path]:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(
            ["run", "hold", "--json", "--no-plots", "--no-mcap", "--out", str(tmp_path), *args]
        )
    assert code == 0, out.getvalue()
    metrics = json.loads(out.getvalue().strip().splitlines()[-1])
    return metrics, Path(metrics["out_dir"])


def test_the_gravity_compensator_removes_the_sag_each_joint_has_under_pid(tmp_path: Path) -> None:
    config = load_config(robot="fixed-base")
    model = config.model
    names = config.joint_names
    load = fixed_base_links(config).gravity.gravity_torque(np.zeros(len(names)))
    gear = np.array([model.joint_figure(n, "stiffness_nm_per_rad") for n in names])
    whole = joint_static_compliance(
        gear,
        [model.joint_figure(n, "position_gain_per_s") for n in names],
        [model.joint_figure(n, "velocity_gain_nms_per_rad") for n in names],
    )
    pid, _ = hold(tmp_path / "pid", "--robot", "fixed-base", "--controller", "pid")
    gc, _ = hold(tmp_path / "gc", "--robot", "fixed-base", "--controller", "gc")
    assert pid["termination"] == gc["termination"] == "completed"
    for i, name in enumerate(names):
        sag = -pid["static_error_rad_by_joint"][name]
        assert load[i] / gear[i] < sag < whole[i] * load[i], name
        assert abs(gc["static_error_rad_by_joint"][name]) < 0.3 * sag, name


def test_on_two_chains_the_robot_writes_the_same_log(tmp_path: Path) -> None:
    two = default_config_text("fixed-base").replace(
        "[[can]]",
        '[[dynamixel]]\nname = "forearm"\nport = "/dev/ttyUSB1"\nbaudrate = 1000000\n\n[[can]]',
    )
    two = two.replace("dynamixel_id = 1\n", 'dynamixel_id = 1\ndynamixel = "rs485"\n')
    two = two.replace("dynamixel_id = 2\n", 'dynamixel_id = 1\ndynamixel = "forearm"\n')
    path = tmp_path / "two_chains.toml"
    path.write_text(two)
    _, one_dir = hold(tmp_path / "one", "--robot", "fixed-base", "--controller", "gc+lqr")
    _, again_dir = hold(tmp_path / "again", "--robot", "fixed-base", "--controller", "gc+lqr")
    _, two_dir = hold(
        tmp_path / "two", "--config", str(path), "--emulate", "--controller", "gc+lqr"
    )
    one = (one_dir / "log.csv").read_bytes()
    assert one == (again_dir / "log.csv").read_bytes()  # lock-step: deterministic
    assert one == (two_dir / "log.csv").read_bytes()
    meta = json.loads((two_dir / "meta.json").read_text())
    assert len(meta["connection"]["dynamixel"]) == 2


def test_without_link_encoders_gc_runs_on_the_motor_encoders_and_the_lqr_is_refused(
    tmp_path: Path,
) -> None:
    bare = default_config_text("fixed-base")
    bare = bare.replace("encoder_node_id = 5", "encoder_node_id = 0")
    bare = bare.replace("encoder_node_id = 6", "encoder_node_id = 0")
    path = tmp_path / "stock_arm.toml"
    path.write_text(bare)
    gc, run_dir = hold(tmp_path / "gc", "--config", str(path), "--emulate", "--controller", "gc")
    assert gc["termination"] == "completed"
    # the motor encoder through the gear stands for the link's: the deflection is not seen
    assert gc["deflection_rad_by_joint"] == {"shoulder": 0.0, "elbow": 0.0}
    header = (run_dir / "log.csv").read_text().splitlines()[0].split(",")
    rows = np.loadtxt(run_dir / "log.csv", delimiter=",", skiprows=1, usecols=range(6, 17))
    link, motor = (
        header.index("link_angle_rad[shoulder]") - 6,
        header.index("motor_angle_rad[shoulder]") - 6,
    )
    np.testing.assert_array_equal(rows[:, link], rows[:, motor])
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
        code = main(
            ["run", "hold", "--config", str(path), "--emulate", "--controller", "gc+lqr"]
            + ["--out", str(tmp_path / "lqr")]
        )
    assert code == 2
    assert "no link encoder" in out.getvalue()
    assert not (tmp_path / "lqr").exists() or not any((tmp_path / "lqr").iterdir())
