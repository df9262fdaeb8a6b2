"""The legs' twin's parts, fast: the figures make the configuration they say and read back from
it, the twin's file reads back as itself, the plant's reading of a humanoid replay is the
drivers' without their quantisation and noise, the block Levenberg-Marquardt finds figures
changed on known "hardware" from a short suspended excitation, and a friction model is chosen
only when it earns its figures.

(The done-when measurement, minutes: tests/hil/test_twin_legs.py.)
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hil.config import load_config
from hil.twin.block_lm import Problem, Replays, Rows, jacobian, normal_equations, solve
from hil.twin.legs import LegsFitOptions, _best_model, _intervals, _weights
from hil.twin.legs_figures import JOINT_FIGURES, leg_figures_of, legs_twin_config
from hil.twin.replay import Reading, replay_goals
from hil.twin.runs import read_run
from hil.twin.toml_file import config_text
from hil.vocabulary import Robot
from sim_backend.friction import GearboxFriction
from tests.support.bench_hardware import record
from tests.support.legs_hardware import LEGS_TRUTH_EMULATOR, legs_truth_config

SHORT_S = 6.5  # of the suspended excitation: its first window's hold and most of its up-sweep


def _host():
    return load_config(robot=Robot.DYROS_JET)


def test_the_figures_make_the_configuration_they_say() -> None:
    truth = legs_truth_config(_host())
    figures = leg_figures_of(truth)
    plant = LEGS_TRUTH_EMULATOR["plant"]
    for key in ("gear_stiffness_nm_per_rad", "position_gain_per_s", "gearbox_load_friction_ratio"):
        np.testing.assert_array_equal(figures.joints[key], plant[key])
    assert [m.value for m in figures.models] == plant["gearbox_friction_model"]
    assert figures.mass_scale == plant["mass_scale"]
    np.testing.assert_array_equal(
        figures.joints["motor_zero_error_rad"], LEGS_TRUTH_EMULATOR["motor_zero_error_rad"]
    )
    # into a configuration from the default and back: the same figures
    again = leg_figures_of(legs_twin_config(_host(), figures))
    for key, values in figures.joints.items():
        np.testing.assert_array_equal(again.joints[key], values, err_msg=key)
    assert again.models == figures.models and again.mass_scale == figures.mass_scale


def test_the_twins_file_reads_back_as_itself() -> None:
    twin = legs_twin_config(_host(), leg_figures_of(legs_truth_config(_host())))
    text = config_text(twin, ["a legs' twin"])  # (asserts that it reads back the same)
    assert "gearbox_friction_model" in text


def test_another_robots_configuration_is_refused() -> None:
    with pytest.raises(ValueError, match="DYROS-JET"):
        leg_figures_of(load_config())


@pytest.fixture(scope="module")
def short_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """6.5 s of the suspended excitation (its first window's hold and most of its up-sweep) on
    the default legs."""
    out = tmp_path_factory.mktemp("legs")
    host = _host()
    return record(host, host, "suspended-chirp", "pid", out, duration_s=SHORT_S).out_dir


def test_the_plants_reading_is_the_drivers_without_their_noise(short_run: Path) -> None:
    run = read_run(short_run)
    plant = replay_goals(run.config, run, Reading.PLANT)
    drivers = replay_goals(run.config, run, Reading.DRIVERS)
    assert not plant.unstable
    assert np.nanmax(np.abs(drivers.link_angle_rad - run.signal("link_angle_rad"))) <= 5.1e-10
    # the link encoders' and the motors' quantisation; the current's noise (20 mA rms)
    assert np.nanmax(np.abs(plant.link_angle_rad - run.signal("link_angle_rad"))) < 3e-5
    assert np.nanmax(np.abs(plant.motor_angle_rad - run.signal("motor_angle_rad"))) < 3e-5
    assert np.nanmax(np.abs(plant.motor_current_a - run.signal("motor_current_a"))) < 0.15


def test_the_fit_finds_stiffness_and_servo_gain_changed_on_the_hardware(short_run: Path) -> None:
    """Known hardware: the default legs with the hip yaws' K 10 % higher and their Kpp 8 %
    lower; the fit starts from the default and, from the hip yaws' sweep, finds both."""
    run = read_run(short_run)
    start = leg_figures_of(run.config)
    truth = start.copy()
    for j in (0, 6):
        truth.joints["gear_stiffness_nm_per_rad"][j] *= 1.10
        truth.joints["position_gain_per_s"][j] *= 0.92
    hardware = legs_twin_config(run.config, truth)
    recorded = record(hardware, run.config, "suspended-chirp", "pid", short_run.parent / "hw",
                      duration_s=SHORT_S)  # fmt: skip
    run = read_run(recorded.out_dir)
    fit_rows = Rows((np.arange(run.ticks) > 5,))
    replays = Replays([run], run.config, workers=1)
    try:
        first = replays.many([start])[0]
        assert first is not None
        weights = _weights(first, fit_rows)
        keys = {j: ("gear_stiffness_nm_per_rad", "position_gain_per_s") for j in (0, 6)}
        problem = Problem(keys, False, fit_rows, weights)
        found, _, _ = solve(replays, problem, start, 6, 1e-6, lambda _: None)
        residual, moved = jacobian(replays, problem, found)
        assert residual is not None
        _, _, _, blocks = normal_equations(problem, residual, moved)
        estimates = _intervals(problem, found, residual, blocks, moved, LegsFitOptions())
    finally:
        replays.close()
    for key in ("gear_stiffness_nm_per_rad", "position_gain_per_s"):
        for j in (0, 6):
            e, true = estimates[key][j], truth.joints[key][j]
            assert e.low <= true <= e.high, (key, j, e, true)
            assert e.relative_half_width < 0.1, (key, j, e)  # it says something (hip yaw K: 6 %)
            assert abs(e.value / start.joints[key][j] - 1) > 0.05  # away from the start
    # the joints not in the problem keep the start's figures
    np.testing.assert_array_equal(
        found.joints["gear_stiffness_nm_per_rad"][1:6],
        start.joints["gear_stiffness_nm_per_rad"][1:6],
    )


def test_a_friction_model_must_earn_its_figures() -> None:
    plain, stribeck = GearboxFriction.COULOMB_VISCOUS, GearboxFriction.STRIBECK
    scores = {plain: np.array([100.0, 100.0]), stribeck: np.array([99.5, 90.0])}
    assert _best_model(scores, 0, 0.01) is plain  # 0.5 % lower: noise
    assert _best_model(scores, 1, 0.01) is stribeck  # 10 % lower: the model
    assert LegsFitOptions().model_margin == 0.01
    assert len(JOINT_FIGURES) == 10
