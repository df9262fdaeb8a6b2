"""Bring-up on the emulated testbed: `hil emulate --config PLANTED` in a child process, and
`hil monitor` / `hil calibrate` attached to it with another configuration (the one a user has
before calibrating: zero offsets). The device is read back with ROBOTIS's SDK."""

from __future__ import annotations

import contextlib
import json
import math
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from hil.config import load_config
from tests.support.rig import read_device, write_torque

MOTOR_COUNT_RAD = 2 * math.pi / 501_923  # H54-200-S500-R: 501,923 pulses per revolution
LINK_COUNT_RAD = 2 * math.pi / 983_040  # RLC2IC on MR075: 120 poles x 8192 counts
PLANTED = {"motor_offset_rad": 0.1234567, "encoder_offset_rad": -0.2345678}

SAMPLE_CONFIG = Path(__file__).parents[2] / "hil" / "data" / "testbed.toml"

pytestmark = pytest.mark.timeout(120)


def _planted_config(path: Path, **keys: float) -> Path:
    """The sample configuration with these [[joint]] keys planted, and gravity off: the
    emulated link stays still at its pose with torque off, as a link held at it would (the
    emulator's plant starts at link angle 0 with the gear unloaded)."""
    text = SAMPLE_CONFIG.read_text()
    for key, value in keys.items():
        text = text.replace(f"\n{key} = 0.0 ", f"\n{key} = {value!r} ", 1)
        assert f"{key} = {value!r}" in text
    text = text.replace("# plant = { load_mass_kg = 3.0 }", "plant = { gravity_m_s2 = 0.0 }")
    path.write_text(text)
    return path


@contextlib.contextmanager
def _emulate(config_path: Path, tmp_path: Path) -> Iterator[Path]:
    """`hil emulate --config FILE` (lock-step); yields the file holding its endpoints line."""
    process = subprocess.Popen(
        [sys.executable, "-m", "hil", "emulate", "--config", str(config_path)],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    try:
        line = process.stdout.readline()
        endpoints = tmp_path / "endpoints.json"
        endpoints.write_text(line)
        yield endpoints
    finally:
        process.terminate()
        process.wait(timeout=10)


def _hil(*args: str, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "hil", *args], capture_output=True, text=True, timeout=timeout
    )


def test_monitor_shows_every_joint_and_leaves_the_device_as_found(tmp_path: Path) -> None:
    planted = _planted_config(tmp_path / "planted.toml", **PLANTED)
    with _emulate(planted, tmp_path) as endpoints_file:
        endpoints = json.loads(endpoints_file.read_text())
        before = read_device(endpoints)
        proc = _hil("monitor", "--attach", str(endpoints_file), "--json", "--duration", "1")
        assert proc.returncode == 0, proc.stderr
        after = read_device(endpoints)
        # torque found on is reported and left on
        write_torque(endpoints, 1)
        torque_on = read_device(endpoints)
        proc_on = _hil("monitor", "--attach", str(endpoints_file), "--duration", "0.5")
        after_on = read_device(endpoints)
    assert (after.torque_enabled, after.goal_position) == (0, before.goal_position)
    assert after == before  # nor any EEPROM item (return delay, position limit)
    samples = [json.loads(line) for line in proc.stdout.splitlines()]
    assert 5 <= len(samples) <= 12  # 10 Hz for 1 s
    joint = samples[-1]["joints"][0]
    assert joint["name"] == "testbed"
    # without calibration, the angles are the planted offsets' images (the plant is at 0)
    assert joint["motor_angle_rad"] == pytest.approx(PLANTED["motor_offset_rad"], abs=2e-5)
    assert joint["link_angle_rad"] == pytest.approx(PLANTED["encoder_offset_rad"], abs=2e-5)
    assert joint["temperature_c"] > 0 and joint["input_voltage_v"] > 0
    assert {"offsets_disagree", "deflection"} <= set(joint["flags"])
    assert joint["torque_enabled"] is False and joint["fault"] == "none"
    assert proc_on.returncode == 0, proc_on.stderr
    assert "torque is ON on testbed" in proc_on.stderr and "TORQUE_ON" in proc_on.stdout
    assert after_on == torque_on and after_on.torque_enabled == 1


def test_ctrl_c_stops_the_monitor_and_leaves_the_device_as_found(tmp_path: Path) -> None:
    with _emulate(_planted_config(tmp_path / "planted.toml"), tmp_path) as endpoints_file:
        endpoints = json.loads(endpoints_file.read_text())
        before = read_device(endpoints)
        process = subprocess.Popen(
            [sys.executable, "-m", "hil", "monitor", "--attach", str(endpoints_file), "--json"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        lines = [process.stdout.readline() for _ in range(3)]  # it is sampling
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=20)
        after = read_device(endpoints)
    assert all(json.loads(line)["joints"] for line in lines)
    assert process.returncode == 0, err
    assert "left as found" in err
    assert after == before


def test_calibrate_recovers_the_planted_offsets_within_one_count(tmp_path: Path) -> None:
    planted = _planted_config(tmp_path / "planted.toml", **PLANTED)
    mine = tmp_path / "mine.toml"
    mine.write_text(SAMPLE_CONFIG.read_text())  # a user's file before calibration
    original = mine.read_text()
    with _emulate(planted, tmp_path) as endpoints_file:
        started = time.monotonic()
        proc = _hil(
            "calibrate", "--config", str(mine), "--attach", str(endpoints_file),
            "--seconds", "0.5", "--write",
        )  # fmt: skip
        elapsed = time.monotonic() - started
    assert proc.returncode == 0, proc.stderr
    calibrated = load_config(mine)
    joint = calibrated.joints[0]
    motor_error = abs(joint.motor_offset_rad - PLANTED["motor_offset_rad"])
    link_error = abs(joint.encoder_offset_rad - PLANTED["encoder_offset_rad"])
    print(f"calibration error: motor {motor_error:.1e}, link {link_error:.1e} rad, {elapsed:.1f} s")
    assert motor_error <= MOTOR_COUNT_RAD
    assert link_error <= LINK_COUNT_RAD
    # the file was edited, not re-serialised: only the two values changed, a backup was kept
    assert Path(str(mine) + ".bak").read_text() == original
    changed = [
        (a, b) for a, b in zip(original.splitlines(), mine.read_text().splitlines(), strict=True)
        if a != b
    ]  # fmt: skip
    assert sorted(a.split("=")[0].strip() for a, _ in changed) == sorted(PLANTED)
    assert all("#" in b for _, b in changed)  # their comments are kept
    assert "motor_offset_rad = " in proc.stdout and "OUTSIDE zero_offset_margin_rad" in proc.stderr
