"""DYROS-JET as its lab ran it (hil/data/dyros_jet_lab.toml): the legs on the lab's two leg
chains with the lab's IDs (psh117/dyros_jet, dyros_jet_model.cpp JOINT_ID; psh117/rt_dynamixel,
dxl_lists.cpp), the servo registers the lab's driver writes at start-up (Position P 96,
Velocity P 500, Velocity I 0), and nothing else changed from the built-in configuration.

Through the emulated buses the registers reach the emulated H54: standing, each joint's servo
holds its load with the static stiffness the registers map to (Kt I = Kpp kv (goal - motor),
no velocity integral to wind the lag out), 2951 N m/rad under the named mapping (sim_backend/
servo.py, H54ServoParams.cascade_at), not the factory registers' 785 (knees 1413)."""

from __future__ import annotations

import contextlib
import io
import json
from importlib import resources
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from hil.cli import main
from hil.config import Config, load_config
from hil.vocabulary import Robot
from hil.wiring.emulation import emulated_joint_stiffness
from sim_backend.servo import H54ServoParams

LAB_CONFIG = Path(str(resources.files("hil").joinpath("data", "dyros_jet_lab.toml")))
# The lab's Dynamixel IDs of the leg joints (dyros_jet_model.cpp) and their chains
# (dxl_lists.cpp: channel 2 "Right Lower body", channel 3 "Left Lower body").
LAB_IDS = {
    "L_HipYaw": 16, "L_HipRoll": 18, "L_HipPitch": 20,
    "L_KneePitch": 22, "L_AnklePitch": 24, "L_AnkleRoll": 26,
    "R_HipYaw": 15, "R_HipRoll": 17, "R_HipPitch": 19,
    "R_KneePitch": 21, "R_AnklePitch": 23, "R_AnkleRoll": 25,
}  # fmt: skip


def _lab() -> Config:
    return load_config(LAB_CONFIG)


def test_the_lab_configuration_has_the_lab_chains_ids_and_registers() -> None:
    lab = _lab()
    assert [d.name for d in lab.dynamixel] == ["right_leg", "left_leg"]
    for joint in lab.joints:
        side = "left_leg" if joint.name.startswith("L_") else "right_leg"
        assert (lab.chain_of(joint), joint.dynamixel_id) == (side, LAB_IDS[joint.name])
        registers = (joint.position_p_gain, joint.velocity_p_gain, joint.velocity_i_gain)
        assert registers == (96, 500, 0), joint.name


def test_it_differs_from_the_built_in_configuration_in_the_servos_and_buses_only() -> None:
    lab, built_in = _lab(), load_config(robot=Robot.DYROS_JET)
    for section in ("loop", "can", "force_torque_sensors", "controller", "walking", "safety"):
        assert getattr(lab, section) == getattr(built_in, section), section
    assert lab.emulator == built_in.emulator
    servo_keys = {"dynamixel_id", "dynamixel", "position_p_gain", "velocity_p_gain"}
    servo_keys |= {"velocity_i_gain"}
    for ours, theirs in zip(lab.joints, built_in.joints, strict=True):
        assert ours.model_dump(exclude=servo_keys) == theirs.model_dump(exclude=servo_keys)


def test_its_model_is_the_servo_its_registers_give_the_emulated_h54() -> None:
    lab = _lab()
    expected = H54ServoParams().cascade_at(96, 500, 0)
    for joint in emulated_joint_stiffness(lab):
        assert joint.servo == expected, joint.name
        name = joint.name
        assert lab.model.joint_figure(name, "position_gain_per_s") == pytest.approx(
            expected.position_gain_per_s
        )
        assert lab.model.joint_figure(name, "velocity_gain_nms_per_rad") == pytest.approx(
            expected.velocity_gain_nms_per_rad, rel=1e-3
        )
    assert expected.velocity_integral_time_s == np.inf


@pytest.mark.slow
def test_standing_through_the_emulated_buses_the_servos_hold_at_the_lab_stiffness(
    tmp_path: Path,
) -> None:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(
            ["run", "stand", "--config", str(LAB_CONFIG), "--emulate", "--controller", "gc"]
            + ["--duration", "1.5", "--json", "--no-plots", "--no-mcap", "--out", str(tmp_path)]
        )
    assert code == 0, out.getvalue()
    metrics = json.loads(out.getvalue().strip().splitlines()[-1])
    assert metrics["termination"] == "completed" and not metrics["fell"]
    run_dir = Path(metrics["out_dir"])
    meta = json.loads((run_dir / "meta.json").read_text())
    assert sorted(meta["connection"]["dynamixel"]) == ["left_leg", "right_leg"]
    # the last 0.25 s at rest: the knees carry ~32 N m each
    log = pd.read_csv(run_dir / "log.csv").iloc[-50:]
    torque_constant = H54ServoParams().torque_constant_nm_per_a
    stiffness = H54ServoParams().cascade_at(96, 500, 0).static_stiffness_nm_per_rad
    for knee in ("L_KneePitch", "R_KneePitch"):
        lag = (log[f"goal_rad[{knee}]"] - log[f"motor_angle_rad[{knee}]"]).mean()
        torque = (log[f"motor_current_a[{knee}]"] * torque_constant).mean()
        assert abs(torque) > 20.0, knee
        assert torque / lag == pytest.approx(stiffness, rel=0.03), knee
