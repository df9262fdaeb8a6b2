"""`hil run identify` (the open-loop excitation experiment) and `hil identify` on its run
directory, on the in-process emulated testbed: the goals stay within the limits and below the
supervisor's rate limit, the run carries what the fit needs, and the fit recovers the
emulator's constants. The full-length run through the embedded emulator and the CLI is in
tests/e2e/test_identify_cli.py."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from hil.cli import main
from hil.config import load_config
from hil.experiments import IDENTIFY, IdentifyExperiment
from hil.identify import ChirpExcitation
from hil.safety import ReferenceOutsideLimits
from hil.session import Session, Setup
from hil.vocabulary import ControllerChoice, ControllerKind
from sim_backend.plant import TestbedPlantParams as PlantParams
from sim_backend.servo import H54ServoParams

CONFIG = load_config()
PERIOD_S = CONFIG.loop.period_s
SHORT = IdentifyExperiment(
    name="identify",
    title="identification, shortened",
    excitation=ChirpExcitation(
        fit_sweep_duration_s=10.0, validation_sweep_duration_s=4.0, settle_duration_s=1.0
    ),
)


def test_the_goals_stay_within_the_limits_and_below_the_supervisors_rate() -> None:
    ticks = int(round(IDENTIFY.duration_s / PERIOD_S))
    offsets = IDENTIFY.goal_offsets(PERIOD_S, ticks, 1)[:, 0]
    joint = CONFIG.joints[0]
    hold = IDENTIFY.excitation.holding_angle_rad
    assert joint.min_angle_rad < hold + offsets.min() < hold + offsets.max() < joint.max_angle_rad
    assert np.abs(offsets).max() == pytest.approx(IDENTIFY.excitation.amplitude_rad, rel=0.02)
    rate = np.abs(np.diff(offsets)).max() / PERIOD_S
    assert rate <= IDENTIFY.excitation.max_goal_rate_rad_s < CONFIG.safety.max_goal_rate_rad_s
    low, high = IDENTIFY.reference_range(1)
    assert low[0] == pytest.approx(hold + offsets.min()) and high[0] == pytest.approx(
        hold + offsets.max()
    )
    # the excitation starts and ends at rest: the hold goal before and after
    assert offsets[0] == 0.0 and abs(offsets[-1]) < 1e-9


def test_an_excitation_faster_than_the_supervisor_allows_is_refused(tmp_path: Path) -> None:
    slow_supervisor = CONFIG.changed("safety", max_goal_rate_rad_s=1.0)
    session = Session(slow_supervisor, Setup.IN_PROCESS, out_root=tmp_path, plots=False)
    session.quiet = True
    with pytest.raises(ReferenceOutsideLimits, match="max_goal_rate_rad_s"):
        session.run_one(SHORT, ControllerChoice(ControllerKind.PID), print_result=False)


@pytest.fixture(scope="module")
def short_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("identify")
    session = Session(CONFIG, Setup.IN_PROCESS, out_root=root, plots=False, quiet=True)
    result = session.run_one(SHORT, ControllerChoice(ControllerKind.PID), print_result=False)
    assert result.ok, result.ending
    return result.out_dir


def test_the_run_follows_the_planned_goals_and_records_what_the_fit_needs(
    short_run: Path,
) -> None:
    summary = json.loads((short_run / "summary.json").read_text())
    meta = json.loads((short_run / "meta.json").read_text())
    metrics = summary["metrics"]
    assert metrics["excitation_coverage"] == 1.0  # the supervisor rewrote no goal
    assert metrics["peak_goal_rate_rad_s"] <= SHORT.excitation.max_goal_rate_rad_s
    assert 0 < metrics["peak_current_a"] < summary["current_limit_a"][0]
    assert metrics["validation_start_s"] == pytest.approx(SHORT.excitation.validation_start_s)
    assert summary["safety_events"] == [] and summary["safety_notices"] == []
    parameters = meta["experiment_parameters"]
    assert parameters["fit_sweep_duration_s"] == 10.0
    assert parameters["max_goal_rate_rad_s"] == SHORT.excitation.max_goal_rate_rad_s


def test_hil_identify_recovers_the_emulators_constants_from_a_short_run(
    short_run: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A 16 s excitation: enough for K, D and the position and velocity gains within 5 %
    (the integral time needs a longer run: the full experiment, tests/e2e)."""
    figure = short_run / "fit.png"
    assert main(["identify", str(short_run), "--json", "--figure", str(figure)]) == 0
    out = capsys.readouterr().out
    result = json.loads(out.strip().splitlines()[-1])
    plant, servo = PlantParams(), H54ServoParams()
    truth = {
        "gear_stiffness_nm_per_rad": plant.gear_stiffness_nm_per_rad,
        "gear_damping_nm_s_per_rad": plant.gear_damping_nms_per_rad,
        "servo_position_gain_per_s": servo.position_gain_per_s,
        "servo_velocity_gain_nm_s_per_rad": servo.velocity_gain_nms_per_rad,
    }
    for key, true in truth.items():
        assert result[key]["value"] == pytest.approx(true, rel=0.05), key
    for key in ("gear_stiffness_nm_per_rad", "gear_damping_nm_s_per_rad", "servo_kp_per_s"):
        entry = result[key]
        assert entry["low"] <= entry["value"] <= entry["high"]
    assert result["given"]["link_inertia_kg_m2"] == CONFIG.model.link_inertia_kg_m2
    assert result["given"]["current_limit_a"] > 0  # read from the actuator by the run
    assert figure.read_bytes()[:4] == b"\x89PNG"
    assert "[model]" in out and "[emulator]" in out
    assert (short_run / "identification.toml").is_file()


def test_hil_identify_reads_a_log_torn_in_its_last_row(
    short_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Issue 25: a log.csv that ends mid-row (a disk that filled up, a writer killed before the
    record kept its lines whole) made `hil identify` die of an IndexError. It is read without
    the torn row, and says so."""
    torn = tmp_path / "torn"
    shutil.copytree(short_run, torn)
    log = torn / "log.csv"
    text = log.read_text()
    log.write_text(text[: len(text) - len(text.splitlines()[-1]) // 2 - 1])  # half a row
    assert main(["identify", str(torn), "--json"]) == 0
    captured = capsys.readouterr()
    assert "last row is torn" in captured.err and str(log) in captured.err
    result = json.loads(captured.out.strip().splitlines()[-1])
    assert result["gear_stiffness_nm_per_rad"]["value"] > 0


def test_hil_identify_refuses_what_is_not_an_identification_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["identify", str(tmp_path / "nowhere")]) == 2
    assert "no such directory" in capsys.readouterr().err
    assert main(["identify", str(tmp_path)]) == 2
    assert "not a run directory" in capsys.readouterr().err
    session = Session(CONFIG, Setup.IN_PROCESS, out_root=tmp_path, plots=False, quiet=True)
    from hil.experiments import IMPACT

    impact = session.run_one(
        IMPACT, ControllerChoice(ControllerKind.PID), duration_s=0.5, print_result=False
    )
    assert main(["identify", str(impact.out_dir)]) == 2
    err = capsys.readouterr().err
    assert "'impact' run, not an identification run" in err and "hil run identify" in err
    meta = json.loads((impact.out_dir / "meta.json").read_text())
    meta["experiment"] = "identify"
    del meta["experiment_parameters"]
    (impact.out_dir / "meta.json").write_text(json.dumps(meta))
    assert main(["identify", str(impact.out_dir)]) == 2
    assert "without the excitation's parameters" in capsys.readouterr().err
