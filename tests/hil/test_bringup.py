"""Bring-up on the in-process bus: the start gate's zero-offset margin, the calibration's
offsets and direction check, the monitor's flags, and the configuration file edited in place.

The emulated robot is built from a PLANTED configuration (its devices mounted with other
offsets / directions) while the loop reads with the user's configuration, as on a robot whose
configuration is not calibrated yet."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from hil.bringup import DirectionCheck, Flag, assess, calibrate, update_config_text
from hil.bringup.calibration import direction_check
from hil.config import Config, ConfigError, load_config, parse_config
from hil.loop.start_gate import StartRefused, check_zero_offsets
from hil.vocabulary import Termination
from hil.wiring.emulation import emulator_spec
from hil.wiring.in_process import InProcessJointBus
from tests.support.rig import run_in_process

LINK_COUNT_RAD = 2 * math.pi / 983_040
MOTOR_COUNT_RAD = 2 * math.pi / 501_923
SAMPLE_TEXT = (Path(__file__).parents[2] / "hil" / "data" / "testbed.toml").read_text()


def _joint(config: Config, **keys: object) -> Config:
    return config.replaced(joints=[config.joints[0].model_copy(update=keys)])


def _planted(**keys: object) -> Config:
    """The emulated robot: these mounting keys, gravity off (the link stays where it is)."""
    config = _joint(load_config(), **keys)
    return config.changed("emulator", plant={"gravity_m_s2": 0.0})


def _bus(config: Config, planted: Config) -> InProcessJointBus:
    return InProcessJointBus(config, emulator_spec(planted))


def test_the_start_gate_refuses_wrong_offsets_and_its_suggested_fix_starts(tmp_path) -> None:
    config = load_config()
    planted = _planted(encoder_offset_rad=0.05)
    result, _ = run_in_process(
        config, "impact", "gc", tmp_path / "a", duration_s=0.1, bus=_bus(config, planted)
    )
    assert result.termination is Termination.START_REFUSED
    text = result.ending.text
    assert "zero_offset_margin_rad = 0.01" in text and "hil calibrate" in text
    assert "encoder_offset_rad (= 0.05" in text  # the planted value, to the encoder's count
    fixed = _joint(config, encoder_offset_rad=0.05)
    result, _ = run_in_process(
        fixed, "impact", "gc", tmp_path / "b", duration_s=0.1, bus=_bus(fixed, planted)
    )
    assert result.termination is Termination.COMPLETED, result.ending


def test_the_zero_offset_check_names_both_keys_with_the_values_that_would_fix_them() -> None:
    config = _joint(
        load_config(),
        motor_offset_rad=0.2,
        motor_direction=-1,
        encoder_offset_rad=-0.1,
        encoder_direction=-1,
    )
    check_zero_offsets(config, 0, motor_rad=0.300, link_rad=0.309)  # within 0.01: passes
    with pytest.raises(StartRefused) as refused:
        check_zero_offsets(config, 0, motor_rad=0.300, link_rad=0.330)
    # deflection +0.03: o_e + d_e * 0.03 = -0.13 makes the link read 0.300; o_m - d_m * 0.03 =
    # 0.23 makes the motor read 0.330 (q = d (r - o): a change of o by x changes q by -d x)
    assert "encoder_offset_rad (= -0.130000" in str(refused.value)
    assert "motor_offset_rad (= 0.230000" in str(refused.value)


@pytest.mark.parametrize("direction", [1, -1])
def test_calibrate_recovers_planted_offsets_within_one_count(direction: int) -> None:
    config = _joint(load_config(), motor_direction=direction, encoder_direction=direction)
    planted = _planted(
        motor_offset_rad=-0.3141,
        encoder_offset_rad=0.2718,
        motor_direction=direction,
        encoder_direction=direction,
    )
    with _bus(config, planted) as bus:
        calibration = calibrate(config, bus, seconds=0.2, sleep=lambda _s: None)
    (joint,) = calibration.joints
    assert joint.samples == 40 and joint.at_rest
    assert abs(joint.motor_offset_rad - -0.3141) <= MOTOR_COUNT_RAD
    assert abs(joint.encoder_offset_rad - 0.2718) <= LINK_COUNT_RAD
    assert joint.direction is DirectionCheck.NOT_MOVED


def test_calibrate_at_another_pose() -> None:
    """Held at q* = 0.3 rad: the offsets are r* - d q*, whatever the pose."""
    config = load_config()
    planted = _planted(motor_offset_rad=0.1, encoder_offset_rad=0.2)
    planted = planted.changed(
        "emulator", plant={"gravity_m_s2": 0.0, "initial_link_angle_rad": 0.3}
    )
    with _bus(config, planted) as bus:
        (joint,) = calibrate(config, bus, seconds=0.1, poses_rad={"testbed": 0.3}).joints
    assert abs(joint.motor_offset_rad - 0.1) <= MOTOR_COUNT_RAD
    assert abs(joint.encoder_offset_rad - 0.2) <= LINK_COUNT_RAD


@pytest.mark.parametrize(("encoder_direction", "expected"), [(1, "agree"), (-1, "disagree")])
def test_moving_the_joint_during_calibration_checks_the_directions(
    encoder_direction: int, expected: str
) -> None:
    """The test's "hand" swings the emulated joint (torque on through the emulator itself, not
    through the read-only bus); an encoder mounted the other way round is found."""
    config = load_config()
    planted = _planted(encoder_direction=encoder_direction)
    bus = _bus(config, planted)
    bus.open()
    testbed = bus.testbed
    assert testbed is not None and testbed.set_torque(0, True)
    reads = [0]
    original_read = bus.read

    def read_and_move():
        reads[0] += 1
        testbed.write_goal(0, 0.1 * math.sin(2 * math.pi * reads[0] / 100))
        return original_read()

    bus.read = read_and_move  # type: ignore[method-assign]
    (joint,) = calibrate(config, bus, seconds=1.0, sleep=lambda _s: None).joints
    assert not joint.at_rest
    assert joint.direction == expected
    assert abs(joint.slope) == pytest.approx(1.0, abs=0.1)


def test_direction_check_against_hand_made_motions() -> None:
    motor = np.linspace(0.0, 0.1, 50)
    assert direction_check(motor, 2 * motor + 1)[0] is DirectionCheck.AGREE
    assert direction_check(motor, -motor)[0] is DirectionCheck.DISAGREE
    assert direction_check(motor * 0.01, motor)[0] is DirectionCheck.NOT_MOVED
    rng = np.random.default_rng(0)
    assert direction_check(motor, rng.normal(0, 1, 50))[0] is DirectionCheck.INCONCLUSIVE


def test_the_configuration_file_is_edited_in_place() -> None:
    updated = update_config_text(
        SAMPLE_TEXT, {"testbed": {"motor_offset_rad": 0.123, "encoder_offset_rad": -1.5}}
    )
    before, after = SAMPLE_TEXT.splitlines(), updated.splitlines()
    changed = [(a, b) for a, b in zip(before, after, strict=True) if a != b]
    assert [b.split("#")[0].strip() for _, b in changed] == [
        "encoder_offset_rad = -1.500000000",
        "motor_offset_rad = 0.123000000",
    ]
    assert [a.split("#")[1] for a, _ in changed] == [b.split("#")[1] for _, b in changed]
    joint = parse_config(updated).joints[0]
    assert (joint.motor_offset_rad, joint.encoder_offset_rad) == (0.123, -1.5)


def test_a_missing_key_is_added_and_other_joints_are_left_alone() -> None:
    text = SAMPLE_TEXT.replace("motor_offset_rad = 0.0 ", "# motor_offset_rad unset ")
    second = (
        '\n[[joint]]\nname = "elbow"  # the second one\ndynamixel_id = 2\nencoder_node_id = 6\n'
        "motor_offset_rad = 0.5\n"
    )
    text = text.replace("\n# --- the controller's model", second + "\n# --- the controller's model")
    updated = update_config_text(text, {"testbed": {"motor_offset_rad": 0.25}})
    config = parse_config(updated)
    assert [j.motor_offset_rad for j in config.joints] == [0.25, 0.5]
    assert "# motor_offset_rad unset" in updated
    with pytest.raises(ConfigError, match="no \\[\\[joint\\]\\] named"):
        update_config_text(text, {"knee": {"motor_offset_rad": 0.0}})


def test_the_monitor_flags_what_is_outside_the_configuration() -> None:
    config = _joint(load_config(), min_angle_rad=-0.05, max_angle_rad=0.05)
    planted = _planted(motor_offset_rad=-0.1)  # reads r = -0.1 at q = 0: out of range, disagrees
    with _bus(config, planted) as bus:
        sample = bus.read()
        sample.motor_current_a[:] = 9.0
        sample.link_valid[:] = False
        status = assess(config, sample, np.array([10.0]))
    (joint,) = status.joints
    assert set(joint.flags) == {
        Flag.OUT_OF_RANGE,
        Flag.OFFSETS_DISAGREE,
        Flag.DEFLECTION,
        Flag.LINK_STALE,
        Flag.CURRENT,  # 9 A > 0.8 x 10 A
    }
    assert joint.motor_angle_rad == pytest.approx(-0.1, abs=MOTOR_COUNT_RAD)
    assert joint.temperature_c > 0 and joint.input_voltage_v > 0
    record = status.record()["joints"][0]
    assert record["fault"] == "none" and "out_of_range" in record["flags"]


def test_bringup_options_are_checked_before_any_port_is_opened(capsys) -> None:
    from hil.cli import main
    from hil.cli.calibrate import parse_poses

    assert main(["monitor", "--rate", "0"]) == 2
    assert "--rate" in capsys.readouterr().err
    assert main(["calibrate", "--write"]) == 2  # --write needs the file to write
    assert "--config" in capsys.readouterr().err
    assert main(["calibrate", "--seconds", "nan"]) == 2
    config = load_config()
    assert parse_poses(["0.3"], config) == {"testbed": 0.3}
    assert parse_poses(["0.3", "testbed=-0.1"], config) == {"testbed": -0.1}
    with pytest.raises(ConfigError, match="no joint 'knee'"):
        parse_poses(["knee=0.1"], config)
    with pytest.raises(ConfigError, match="NAME=RAD"):
        parse_poses(["testbed=up"], config)
