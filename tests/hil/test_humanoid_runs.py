"""DYROS-JET standing and pushed, on the product's loop (in-process emulated legs).

What is checked against analysis, not against the runs' own output:
- the gravity compensator holds the posture the springs give away without it (Sec. III-A):
  the pelvis tilts less with GC than with position control alone;
- a push F at the pelvis's centre of mass, at height h, moves the ZMP forward by
  (F h - m a h_com) / (m g): the quasi-static F h / (m g) less what the robot's own forward
  acceleration a takes. A robot held by its feet accelerates little: between half and 1.5 times
  the quasi-static figure (measured: 0.094 m against 0.116 m).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from controller.humanoid import LegModel
from hil.config import load_config, robot_description_text
from hil.experiments import PUSH, STAND
from hil.experiments.humanoid import StandingKinematics
from tests.support.rig import assert_log_complete, run_in_process

pytestmark = pytest.mark.slow

STAND_S = 2.0  # 1 s to settle on the springs, 1 s measured


@pytest.fixture(scope="module")
def config():
    return load_config(robot="dyros-jet")


def test_gravity_compensation_keeps_the_pelvis_more_upright(config, tmp_path: Path) -> None:
    tilt = {}
    for controller in ("pid", "gc"):
        result, run = run_in_process(
            config, STAND, controller, tmp_path / controller, duration_s=STAND_S
        )
        assert result.ok, result.ending
        assert_log_complete(run)
        metrics = result.metrics
        assert metrics["fell"] is False
        for key in ("pelvis_tilt_rad", "max_deflection_rad", "zmp_max_error_m"):
            assert np.isfinite(metrics[key]), key
        tilt[controller] = metrics["pelvis_tilt_rad"]
        # the ZMP stays well inside the feet (the soles are 0.30 m long, 0.17 m wide)
        assert metrics["zmp_max_error_m"] < 0.05
    assert tilt["gc"] < 0.8 * tilt["pid"], tilt


def test_a_push_moves_the_zmp_by_its_moment(config, tmp_path: Path) -> None:
    push = PUSH.world.pelvis_pushes[0]
    duration = push.start_s + push.duration_s + 0.3
    result, run = run_in_process(config, PUSH, "gc", tmp_path, duration_s=duration)
    assert result.ok, result.ending
    kinematics = StandingKinematics.of(run.data)
    start = run.data.experiment_start_s + push.start_s
    time_s = run.data.time_s
    before = kinematics.zmp_m[np.flatnonzero(time_s < start)[-1]]
    during = (time_s >= start) & (time_s < start + push.duration_s + 0.1)
    forward = np.nanmax(kinematics.zmp_m[during, 0] - before[0])

    urdf_text = robot_description_text(config)
    model = LegModel(urdf_text)
    q = model.standing_configuration(np.asarray(PUSH.posture_rad), side=0)
    pelvis_com_height_m = _pelvis_com_height(urdf_text, q)
    quasi_static = push.force_n[0] * pelvis_com_height_m / (model.total_mass_kg * 9.81)
    assert 0.5 * quasi_static < forward < 1.5 * quasi_static, (forward, quasi_static)
    assert result.metrics["zmp_excursion_m"] >= forward - 1e-9
    assert result.metrics["fell"] is False


def _pelvis_com_height(urdf_text: str, q: np.ndarray) -> float:
    """Height of the pelvis link's own centre of mass (where the emulator applies the push:
    MuJoCo's xfrc_applied acts at the body's CoM) at the floating-base configuration q."""
    import pinocchio as pin

    pelvis = next(
        link for link in ET.fromstring(urdf_text).iter("link") if link.get("name") == "base_link"
    )
    offset = np.array([float(v) for v in pelvis.find("inertial/origin").get("xyz").split()])
    rotation = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
    return float((q[:3] + rotation @ offset)[2])
