"""A chain of MANIPULATOR-H's three models (H54-200-S500-R, H54-100-S500-R, H42-20-S300-R) on
one emulated line, end to end: `hil emulate --config MIXED` in a child process, `hil scan` finds
each ID with its model, `hil monitor` reads every joint in its own units (device values read
back with ROBOTIS's SDK) and names each joint's actuator."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest
from dynamixel_sdk import COMM_SUCCESS, PacketHandler, PortHandler

from tests.e2e.test_bringup import SAMPLE_CONFIG, _emulate, _hil

pytestmark = pytest.mark.timeout(120)

MIXED = (
    ("shoulder", 1, "H54-200-S500-R"),
    ("elbow", 2, "H54-100-S500-R"),
    ("wrist", 3, "H42-20-S300-R"),
)
PULSES_PER_REV = {1: 501_923, 2: 501_923, 3: 303_750}  # e-Manual resolutions


PLANTED_OFFSET_RAD = {1: 0.1234567, 2: -0.2345678, 3: 0.3456789}


def _mixed_config(path: Path, *, planted: bool = False) -> Path:
    """The sample configuration with three joints, one per model, and gravity off (the links
    stay where the emulator puts them, torque off); `planted`: each actuator mounted with an
    offset (the emulator's device then reads it; a configuration without it shows it)."""
    text = SAMPLE_CONFIG.read_text()
    start = text.index("\n[[joint]]\n") + 1
    end = text.index("\n# ---", start)
    block = text[start:end]
    joints = []
    for name, dxl_id, model in MIXED:
        joint = block.replace('name = "testbed"', f'name = "{name}"\nactuator = "{model}"')
        joint = joint.replace("dynamixel_id = 1", f"dynamixel_id = {dxl_id}")
        joint = joint.replace("encoder_node_id = 5", f"encoder_node_id = {4 + dxl_id}")
        if planted:
            offset = PLANTED_OFFSET_RAD[dxl_id]
            joint = joint.replace("motor_offset_rad = 0.0 ", f"motor_offset_rad = {offset!r} ")
            assert f"motor_offset_rad = {offset!r}" in joint
        joints.append(joint)
    text = text[:start] + "\n".join(joints) + text[end:]
    text = text.replace("# plant = { load_mass_kg = 3.0 }", "plant = { gravity_m_s2 = 0.0 }")
    text = text.replace("node_id = 10 ", "node_id = 0 ")  # no force sensor (its ID is free)
    path.write_text(text)
    return path


def _present_positions(endpoints: dict) -> dict[int, int]:
    port = PortHandler(endpoints["dynamixel_port"])
    assert port.openPort() and port.setBaudRate(int(endpoints["baudrate"]))
    packet = PacketHandler(2.0)
    try:
        out = {}
        for _, dxl_id, _ in MIXED:
            value, result, error = packet.read4ByteTxRx(port, dxl_id, 611)
            assert (result, error) == (COMM_SUCCESS, 0)
            out[dxl_id] = value - (1 << 32) if value >= 1 << 31 else value
        return out
    finally:
        port.closePort()


def test_a_mixed_chain_is_scanned_and_monitored(tmp_path: Path) -> None:
    config = _mixed_config(tmp_path / "mixed.toml")
    planted = _mixed_config(tmp_path / "planted.toml", planted=True)
    with _emulate(planted, tmp_path) as endpoints_file:
        endpoints = json.loads(endpoints_file.read_text())
        port, baud = endpoints["dynamixel_port"], str(endpoints["baudrate"])
        scan = _hil("scan", "--port", port, "--baudrate", baud, "--json")
        assert scan.returncode == 0, scan.stderr
        found = {d["id"]: (d["model"], d["supported"]) for d in json.loads(scan.stdout)["devices"]}
        assert found == {dxl_id: (model, True) for _, dxl_id, model in MIXED}
        monitor = _hil(
            "monitor",
            "--attach",
            str(endpoints_file),
            "--config",
            str(config),
            "--json",
            "--duration",
            "1",
        )
        assert monitor.returncode == 0, monitor.stderr
        pulses = _present_positions(endpoints)
        table = _hil(
            "monitor",
            "--attach",
            str(endpoints_file),
            "--config",
            str(config),
            "--duration",
            "0.3",
        )
        assert table.returncode == 0, table.stderr
    samples = [json.loads(line) for line in monitor.stdout.splitlines() if line.strip()]
    assert samples
    last = samples[-1]["joints"]
    assert [(j["name"], j["actuator"]) for j in last] == [(n, m) for n, _, m in MIXED]
    for joint, (_, dxl_id, _) in zip(last, MIXED, strict=True):
        assert "no_reply" not in joint["flags"]
        # the motor angle the monitor shows is the device's pulses in ITS model's units
        expected = pulses[dxl_id] * 2 * math.pi / PULSES_PER_REV[dxl_id]
        assert joint["motor_angle_rad"] == pytest.approx(expected, abs=1e-4)
        assert joint["motor_angle_rad"] == pytest.approx(PLANTED_OFFSET_RAD[dxl_id], abs=2e-3)
    for _, _, model in MIXED:
        assert model in table.stdout


def test_a_configured_model_the_driver_does_not_know_is_refused_naming_the_key(
    tmp_path: Path,
) -> None:
    config = _mixed_config(tmp_path / "mixed.toml")
    config.write_text(config.read_text().replace('"H42-20-S300-R"', '"L42-10-S300-R"'))
    proc = subprocess.run(
        [sys.executable, "-m", "hil", "monitor", "--config", str(config), "--duration", "0.1"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2, proc.stderr
    assert "[[joint]] 'wrist' actuator" in proc.stderr
    assert "not the PRO layout" in proc.stderr
