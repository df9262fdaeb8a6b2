"""ROBOTIS MANIPULATOR-H (hil/robots/manipulator_h/) end to end on the emulated buses: its one
RS-485 chain mixes three models (IDs 1-2 H54-200-S500-R, 3-4 H54-100-S500-R, 5-6 H42-20-S300-R,
as ROBOTIS's manager configures it); `hil scan` finds each ID with its model, `hil monitor`
reads all six joints, and a lock-step hold completes with every joint's gear deflected by the
static load its URDF predicts (K theta = tau_g, the joints coupled: joint2 carries joints 3-6)."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import numpy as np
import pytest

from hil.cli import main
from hil.config import default_config_text, load_config
from hil.robots.fixed_base.model import fixed_base_links
from tests.e2e.test_bringup import _emulate, _hil

pytestmark = pytest.mark.timeout(300)

MODELS = {1: "H54-200-S500-R", 2: "H54-200-S500-R", 3: "H54-100-S500-R"}
MODELS |= {4: "H54-100-S500-R", 5: "H42-20-S300-R", 6: "H42-20-S300-R"}


def test_its_mixed_chain_is_scanned_and_monitored(tmp_path: Path) -> None:
    config = tmp_path / "manipulator_h.toml"
    config.write_text(default_config_text("manipulator-h"))
    with _emulate(config, tmp_path) as endpoints_file:
        endpoints = json.loads(endpoints_file.read_text())
        port, baud = endpoints["dynamixel_port"], str(endpoints["baudrate"])
        scan = _hil("scan", "--port", port, "--baudrate", baud, "--json")
        assert scan.returncode == 0, scan.stderr
        found = {d["id"]: d["model"] for d in json.loads(scan.stdout)["devices"]}
        monitor = _hil(
            "monitor", "--attach", str(endpoints_file), "--config", str(config), "--json",
            "--duration", "1",
        )  # fmt: skip
        assert monitor.returncode == 0, monitor.stderr
    assert baud == "1000000" and found == MODELS
    last = [json.loads(line) for line in monitor.stdout.splitlines() if line.strip()][-1]
    assert [(j["name"], j["actuator"]) for j in last["joints"]] == [
        (f"joint{i}", MODELS[i]) for i in range(1, 7)
    ]
    assert not any("no_reply" in j["flags"] for j in last["joints"])


@pytest.mark.slow
def test_a_lockstep_hold_deflects_each_gear_by_its_coupled_static_load(tmp_path: Path) -> None:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(
            ["run", "arm-hold", "--robot", "manipulator-h", "--controller", "gc", "--json"]
            + ["--no-plots", "--no-mcap", "--out", str(tmp_path)]
        )
    assert code == 0, out.getvalue()
    metrics = json.loads(out.getvalue().strip().splitlines()[-1])
    assert metrics["termination"] == "completed"
    config = load_config(robot="manipulator-h")
    names = config.joint_names
    load = fixed_base_links(config).gravity.gravity_torque(np.zeros(6))
    stiffness = np.array([config.model.joint_figure(n, "stiffness_nm_per_rad") for n in names])
    deflection = np.array([metrics["deflection_rad_by_joint"][n] for n in names])
    # link - motor = -tau_g / K (tau_g < 0: the arm's weight pulls the links down)
    loaded = np.abs(load) > 0.1
    assert loaded.tolist() == [False, True, True, False, True, False]
    np.testing.assert_allclose(deflection[loaded], -load[loaded] / stiffness[loaded], rtol=0.05)


@pytest.mark.slow
def test_a_lockstep_contact_reads_the_block_s_force_sensor_and_pid_is_stopped(
    tmp_path: Path,
) -> None:
    # pid drives the tool into the block past it (arm-contact): the block's CAN force sensor,
    # brought up over SDO with the six link encoders, reads the press, and the current guard
    # (on in the built-in configuration) stops the run before the actuator's own protection
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(
            ["run", "arm-contact", "--robot", "manipulator-h", "--controller", "pid", "--json"]
            + ["--duration", "4", "--no-plots", "--no-mcap", "--out", str(tmp_path)]
        )
    metrics = json.loads(out.getvalue().strip().splitlines()[-1])
    assert code == 1, out.getvalue()
    assert metrics["termination"] == "safety stop: current (back_off)"
    assert 2.1 < metrics["contact_time_s"] < 2.4  # the elbow reaches the block near 0.2 rad
    assert metrics["peak_contact_force_n"] > 30.0 and not metrics["overload_tripped"]
