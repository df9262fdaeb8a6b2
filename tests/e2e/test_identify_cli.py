"""The issue's done-criterion, as a user runs it: `hil run identify` on the embedded emulated
testbed (a `hil emulate` child, the real drivers on the wire), then `hil identify RUN --json`
recovers the emulator's constants within 5 %.

The paper's first-order Kp of (4) is no constant of the emulated servo: the gearbox's Coulomb
friction adds a lag that (4) reads as a slower servo (hil/identify). It is checked against the
servo's position gain with its own, honest bound, not the 5 %.

    .venv/bin/pytest -q -s -m slow tests/e2e/test_identify_cli.py   (prints the table)
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from sim_backend.plant import TestbedPlantParams as PlantParams
from sim_backend.servo import H54ServoParams

TOLERANCE = 0.05


def _hil(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "hil", *args], capture_output=True, text=True, timeout=600
    )


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_hil_run_identify_then_hil_identify_recovers_the_emulator(tmp_path: Path) -> None:
    run = _hil("run", "identify", "--out", str(tmp_path), "--json")
    assert run.returncode == 0, run.stderr
    out_dir = Path(json.loads(run.stdout.strip().splitlines()[-1])["out_dir"])
    fit = _hil("identify", str(out_dir), "--json")
    assert fit.returncode == 0, fit.stderr
    result = json.loads(fit.stdout.strip().splitlines()[-1])
    plant, servo = PlantParams(), H54ServoParams()
    truth = {
        "gear_stiffness_nm_per_rad": plant.gear_stiffness_nm_per_rad,
        "gear_damping_nm_s_per_rad": plant.gear_damping_nms_per_rad,
        "servo_position_gain_per_s": servo.position_gain_per_s,
        "servo_velocity_gain_nm_s_per_rad": servo.velocity_gain_nms_per_rad,
        "servo_velocity_integral_time_s": servo.velocity_integral_time_s,
        "servo_kp_per_s": servo.position_gain_per_s,  # (4) against the position gain
    }
    print(f"\n`hil identify {out_dir} --json`")
    header = ("parameter", "true", "identified", "95 % interval", "error")
    print("{:34s} {:>8s} {:>11s} {:>22s} {:>7s}".format(*header))
    for key, true in truth.items():
        entry = result[key]
        error = 100 * (entry["value"] / true - 1)
        print(
            f"{key:34s} {true:8.4g} {entry['value']:11.5g} "
            f"[{entry['low']:9.5g}, {entry['high']:9.5g}] {error:+6.1f}%"
        )
    for key, true in truth.items():
        if key != "servo_kp_per_s":
            assert result[key]["value"] == pytest.approx(true, rel=TOLERANCE), key
    # (4): below the position gain by the friction's lag, 10-20 % at this amplitude
    assert 0.8 * servo.position_gain_per_s < result["servo_kp_per_s"]["value"]
    assert result["servo_kp_per_s"]["value"] < 0.9 * servo.position_gain_per_s
    assert (out_dir / "identification.png").is_file()
