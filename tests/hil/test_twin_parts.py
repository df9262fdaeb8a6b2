"""The twin's parts, fast: replays on the emulator that recorded a run give it back, the figures
make the configuration they say, the twin's file reads back as itself, and what makes a fit
untrustworthy is said.

(The fit itself, minutes: tests/hil/test_twin_bench.py; the command: tests/e2e/test_twin_cli.py.)
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from hil.config import load_config, parse_config
from hil.controllers.choice import choose
from hil.robots import get_experiment
from hil.session.session import Session, Setup
from hil.twin.figures import FIGURES, figures_of, link_figures, twin_config
from hil.twin.fit import Estimate, FitOptions, _judge_data, _judge_intervals
from hil.twin.replay import Reading, replay_closed_loop, replay_goals
from hil.twin.runs import NotATwinRun, read_run
from hil.twin.toml_file import config_text
from hil.wiring.emulation import plant_servo_noise
from sim_backend.friction import GearboxFriction


def _run(tmp_path: Path, experiment: str, controller: str, config=None) -> Path:
    config = config or load_config()
    session = Session(config, Setup.IN_PROCESS, out_root=tmp_path, plots=False, quiet=True,
                      mcap=False)  # fmt: skip
    chosen = get_experiment(experiment)
    result = session.run_one(chosen, choose(controller, config, chosen), print_result=False)
    return result.out_dir


def test_replays_on_the_recording_emulator_give_the_run_back(tmp_path: Path) -> None:
    run = read_run(_run(tmp_path, "contact", "pid"))
    closed = replay_closed_loop(run.config, run)
    opened = replay_goals(run.config, run, Reading.DRIVERS)
    plant = replay_goals(run.config, run, Reading.PLANT)
    for signal in ("motor_angle_rad", "link_angle_rad", "motor_current_a"):
        recorded = run.signal(signal)
        assert np.array_equal(closed.signal(signal), recorded), signal
        assert np.nanmax(np.abs(opened.signal(signal) - recorded)) <= 5.1e-10  # 9 decimals
    # the plant's own state: within the encoders' quantisation and the current's noise
    assert np.nanmax(np.abs(plant.link_angle_rad - run.signal("link_angle_rad"))) < 3e-5
    assert np.nanmax(np.abs(plant.motor_current_a - run.signal("motor_current_a"))) < 0.15
    assert np.array_equal(closed.force_n, run.force())


def test_a_changed_emulator_replays_otherwise(tmp_path: Path) -> None:
    run = read_run(_run(tmp_path, "impact", "gc+lqr+dob"))
    other = run.config.changed("emulator", plant={"gear_stiffness_nm_per_rad": 1500.0})
    replayed = replay_closed_loop(other, run)
    assert np.nanmax(np.abs(replayed.link_angle_rad - run.signal("link_angle_rad"))) > 5e-4


def test_figures_make_the_configuration_they_say() -> None:
    base = load_config()
    wanted = {
        "gear_stiffness_nm_per_rad": 1700.0,
        "position_gain_per_s": 12.5,
        "velocity_integral_time_s": 9.0,
        "link_mass_kg": 0.95,
        "load_mass_kg": 0.65,
        "gearbox_stribeck_friction_nm": 1.5,
        "gearbox_stribeck_velocity_rad_s": 0.08,
        "motor_zero_error_rad": -2.5e-3,
    }
    twin = twin_config(base, wanted, GearboxFriction.STRIBECK)
    got = figures_of(twin)
    for key, value in wanted.items():
        assert got[key] == pytest.approx(value, rel=1e-12), key
    plant = plant_servo_noise(twin)[0]
    assert plant.gearbox_friction.law is GearboxFriction.STRIBECK
    inertia, moment = link_figures(plant)
    assert moment == pytest.approx(0.95 * 0.35 + 0.65 * 0.7)
    assert inertia == pytest.approx(plant.link_inertia_kg_m2, rel=1e-3)  # + the rod's radius
    assert set(FIGURES) <= set(got)
    # the file reads back as the same configuration, every section but [emulator] as recorded
    again = parse_config(config_text(twin), "<twin>")
    assert again.record() | {"source": 0} == twin.record() | {"source": 0}
    assert again.controller == base.controller and again.model == base.model


def test_gain_registers_in_force_scale_the_twins_servo() -> None:
    base = load_config()
    joint = base.joints[0].model_copy(update={"position_p_gain": 64})
    base = base.replaced(joints=[joint])
    assert figures_of(base)["position_gain_per_s"] == pytest.approx(20.0)
    twin = twin_config(base, {"position_gain_per_s": 15.0}, GearboxFriction.COULOMB_VISCOUS)
    assert twin.emulator.servo["position_gain_per_s"] == pytest.approx(7.5)  # at register 32
    assert figures_of(twin)["position_gain_per_s"] == pytest.approx(15.0)


def test_untrusted_fits_are_said(tmp_path: Path) -> None:
    problems: list[str] = []
    estimates = {
        "gear_stiffness_nm_per_rad": Estimate(2000.0, 1000.0, 3000.0, "N m/rad"),
        "gear_damping_nms_per_rad": Estimate(100.0, 99.0, 101.0, "N m s/rad"),
        "motor_zero_error_rad": Estimate(0.0, -0.002, 0.002, "rad"),
    }
    _judge_intervals(list(estimates), estimates, FitOptions(), problems)
    assert len(problems) == 2
    assert "gear_stiffness_nm_per_rad" in problems[0] and "not determined" in problems[0]
    assert "motor_zero_error_rad" in problems[1] and "mrad" in problems[1]
    # a run the supervisor stopped, too short to fit
    run = read_run(_run(tmp_path, "contact", "pid"))
    problems = []
    assert not _judge_data([run], ((1, 500),), run.config, problems)
    assert "499 samples" in problems[0]
    problems = []
    assert _judge_data([run], ((1, run.ticks),), run.config, problems)
    assert any("did not complete" in p for p in problems), problems
    assert any("integral time" in p for p in problems), problems


def test_a_directory_that_is_not_a_run(tmp_path: Path) -> None:
    with pytest.raises(NotATwinRun, match="not a run directory"):
        read_run(tmp_path)
    assert math.isfinite(FitOptions().residual_limit_rad)
