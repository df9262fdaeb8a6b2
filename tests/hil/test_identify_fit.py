"""The fits on data from their own model (truth known exactly), the intervals' coverage, the
outputs (JSON, TOML fragment, figure) and reading a run log's columns."""

from __future__ import annotations

import dataclasses
import json
import math
import tomllib

import numpy as np
import pytest
import scipy.signal

from hil.config import load_config
from hil.controllers.paper_factory import gc_compliance
from hil.identify import (
    ChirpExcitation,
    GearParams,
    IdentificationOptions,
    JointLog,
    KnownJointFigures,
    LogFormatError,
    MotorParams,
    Parameter,
    ServoParams,
    Status,
    chirp_goal_offsets,
    fit_first_order_servo,
    fit_gear,
    identify,
    render_config_fragment,
    result_to_json,
    write_identification_figure,
)
from hil.identify.models import simulate_joint

PERIOD_S = 0.005
# Sensor resolutions of the testbed (H54 e-Manual units, RLS RLC2IC on MR075)
MOTOR_STEP_RAD = 2 * math.pi / 501_923
VELOCITY_STEP_RAD_S = 0.00199234 * 2 * math.pi / 60
CURRENT_STEP_A = 33.0 / 2048
LINK_STEP_RAD = 2 * math.pi / 983_040

KNOWN = KnownJointFigures(link_inertia_kg_m2=0.3, gravity_moment_kg_m=0.5)
GEAR = GearParams(1700.0, 80.0, 0.0)
SERVO = ServoParams(12.0, 70.0, 3.0, 0.0)
MOTOR = MotorParams(0.2, 0.5, 2.0)
EXCITATION = ChirpExcitation(
    fit_sweep_duration_s=12.0, validation_sweep_duration_s=4.0, settle_duration_s=1.0
)


def quantise(value: np.ndarray, step: float) -> np.ndarray:
    return np.round(value / step) * step


def synthetic_log() -> JointLog:
    """The fitted model itself driven by the chirp, measured at the sensors' resolutions;
    it starts as torque comes on: gear pre-deflected by gravity, servo integral zero."""
    offsets = chirp_goal_offsets(EXCITATION).goal_offset_rad
    n = len(offsets)
    motor0 = KNOWN.gravity_torque_nm / GEAR.stiffness_nm_per_rad  # link horizontal at rest
    zeros = np.zeros(n)
    start = JointLog(
        np.arange(n) * PERIOD_S,
        motor0 + offsets,
        np.full(n, motor0),
        zeros,
        zeros,
        zeros,
        source="synthetic",
    )
    sim = simulate_joint(start, GEAR, SERVO, MOTOR, KNOWN, 0.001)
    return JointLog(
        start.time_s,
        start.goal_rad,
        quantise(sim.motor_angle_rad, MOTOR_STEP_RAD),
        quantise(sim.link_angle_rad, LINK_STEP_RAD),
        quantise(sim.motor_velocity_rad_s, VELOCITY_STEP_RAD_S),
        quantise(sim.motor_current_a, CURRENT_STEP_A),
        source="synthetic",
    )


@pytest.fixture(scope="module")
def result():
    options = IdentificationOptions(validation_start_s=EXCITATION.validation_start_s)
    return identify([synthetic_log()], KNOWN, options)


def test_fits_recover_their_own_models_constants(result) -> None:
    truth = {
        # the link model is continuous, the data come from 1 ms steps: 2 % for the gear
        Parameter.GEAR_STIFFNESS: (GEAR.stiffness_nm_per_rad, 0.02),
        Parameter.GEAR_DAMPING: (GEAR.damping_nms_per_rad, 0.02),
        Parameter.POSITION_GAIN: (SERVO.position_gain_per_s, 0.005),
        Parameter.VELOCITY_GAIN: (SERVO.velocity_gain_nms_per_rad, 0.005),
        Parameter.VELOCITY_INTEGRAL_TIME: (SERVO.velocity_integral_time_s, 0.01),
        # a nuisance: the one-period predictions start from a differentiated link angle,
        # whose error the motor inertia absorbs (13 % here)
        Parameter.MOTOR_INERTIA: (MOTOR.reflected_inertia_kg_m2, 0.2),
        Parameter.MOTOR_COULOMB_FRICTION: (MOTOR.coulomb_friction_nm, 0.01),
    }
    for parameter, (value, tolerance) in truth.items():
        assert result[parameter].value == pytest.approx(value, rel=tolerance), parameter
    # The offset absorbs the gear's discretisation bias: K (delta + delta_0) balances gravity,
    # 0.7 % of the 2.9 mrad static deflection is 2e-5 rad (3 link-encoder counts).
    assert result[Parameter.DEFLECTION_OFFSET].value == pytest.approx(0.0, abs=4e-5)
    assert result[Parameter.CURRENT_LIMIT].status is Status.LOWER_BOUND


def test_gear_scale_is_the_given_link_inertias() -> None:
    """Kinematics fix K/I and D/I: a link inertia 10 % too large gives K and D 10 % too large
    (the offset, a ratio of torques, stays)."""
    log = synthetic_log()
    options = IdentificationOptions(validation_start_s=EXCITATION.validation_start_s)
    right, _ = fit_gear([log], KNOWN, options)
    heavier = dataclasses.replace(
        KNOWN,
        link_inertia_kg_m2=1.1 * KNOWN.link_inertia_kg_m2,
        gravity_moment_kg_m=1.1 * KNOWN.gravity_moment_kg_m,
    )
    scaled, _ = fit_gear([log], heavier, options)
    assert scaled.stiffness_nm_per_rad == pytest.approx(1.1 * right.stiffness_nm_per_rad, rel=1e-4)
    assert scaled.damping_nms_per_rad == pytest.approx(1.1 * right.damping_nms_per_rad, rel=1e-4)
    assert scaled.deflection_offset_rad == pytest.approx(right.deflection_offset_rad, abs=1e-8)


def test_held_out_quality_is_reported_for_every_model(result) -> None:
    signals = {(q.model, q.signal): q for q in result.quality}
    assert len(signals) == 6
    gear = signals[("gear (1) from measured motor", "deflection")]
    assert gear.vaf_percent > 99.0
    assert all(q.samples == round(4.0 / PERIOD_S) + round(1.0 / PERIOD_S) for q in result.quality)
    whole = signals[("whole joint, simulated", "motor angle")]
    assert whole.vaf_percent > 99.0


def test_json_holds_value_and_interval_for_the_issues_keys(result) -> None:
    text = json.dumps(result_to_json(result), allow_nan=False)  # strict JSON: no NaN/inf
    data = json.loads(text)
    for key in (
        "gear_stiffness_nm_per_rad",
        "gear_damping_nm_s_per_rad",
        "gear_damping_nms_per_rad",
        "servo_kp_per_s",
    ):
        entry = data[key]
        assert entry["low"] <= entry["value"] <= entry["high"]
    limit = data["servo_current_limit_a"]
    assert limit["value"] is None and limit["high"] is None and limit["low"] > 0
    assert data["given"]["link_inertia_kg_m2"] == KNOWN.link_inertia_kg_m2


def test_config_fragment_is_toml_with_the_controllers_and_emulators_keys(result) -> None:
    text = render_config_fragment(result, "testbed")
    data = tomllib.loads(text)
    model = data["model"]["joint"]["testbed"]
    assert model["stiffness_nm_per_rad"] == pytest.approx(
        result[Parameter.GEAR_STIFFNESS].value, rel=1e-5
    )
    assert model["damping_nms_per_rad"] == pytest.approx(
        result[Parameter.GEAR_DAMPING].value, rel=1e-5
    )
    assert model["servo_gain_per_s"] == pytest.approx(result[Parameter.SERVO_KP].value, rel=1e-5)
    # the configuration takes the model table as it is
    configured = load_config().changed("model", joint=data["model"]["joint"])
    assert configured.model.joint_figure("testbed", "stiffness_nm_per_rad") == pytest.approx(
        model["stiffness_nm_per_rad"]
    )
    # ... and the servo's cascade, under the same names as the emulator's: the gravity
    # compensator's joint compliance is then the identified joint's 1/K + 1/(Kpp kv)
    for key, parameter in (
        ("position_gain_per_s", Parameter.POSITION_GAIN),
        ("velocity_gain_nms_per_rad", Parameter.VELOCITY_GAIN),
        ("velocity_integral_time_s", Parameter.VELOCITY_INTEGRAL_TIME),
    ):
        assert model[key] == pytest.approx(result[parameter].value, rel=1e-5)
        assert model[key] == pytest.approx(data["emulator"]["servo"][key])
    expected = 1 / model["stiffness_nm_per_rad"] + 1 / (
        model["position_gain_per_s"] * model["velocity_gain_nms_per_rad"]
    )
    assert gc_compliance(configured)[0] == pytest.approx(expected, rel=1e-9)
    servo = data["emulator"]["servo"]
    assert set(servo) == {
        "position_gain_per_s",
        "velocity_gain_nms_per_rad",
        "velocity_integral_time_s",
    }
    assert set(data["emulator"]["plant"]) == {
        "gear_stiffness_nm_per_rad",
        "gear_damping_nms_per_rad",
    }


def test_figure_is_written_without_a_display(result, tmp_path) -> None:
    path = write_identification_figure(result, tmp_path / "identify.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert path.stat().st_size > 20_000


def test_intervals_cover_the_truth_under_correlated_noise() -> None:
    """(4) fitted to its own response plus AR(1) noise (rho = 0.95): the sandwich intervals
    should hold the true Kp in about 95 % of repeats (i.i.d. intervals would hold it far less
    often), and be about as wide as the estimates actually scatter."""
    rng = np.random.default_rng(7)
    n, kp = 2000, 8.0
    t = np.arange(n) * PERIOD_S
    goal = 0.05 * scipy.signal.chirp(t, 0.3, t[-1], 6.0, method="logarithmic", phi=-90)
    from hil.identify.models import first_order_response

    clean = first_order_response(goal, 0.0, kp, PERIOD_S)
    options = IdentificationOptions(holdout_fraction=0.0, first_order_highpass_hz=0.05)
    estimates, covered, halves = [], 0, []
    repeats = 60
    for _ in range(repeats):
        noise = scipy.signal.lfilter([1.0], [1.0, -0.95], rng.normal(0, 2e-4, n))
        zeros = np.zeros(n)
        log = JointLog(t, goal, clean + noise, zeros, zeros, zeros)
        value, outcome = fit_first_order_servo([log], options)
        estimates.append(value)
        covered += outcome.low[0] <= kp <= outcome.high[0]
        halves.append((outcome.high[0] - outcome.low[0]) / 2)
    assert covered / repeats >= 0.85
    scatter = 1.96 * float(np.std(estimates))
    assert 0.5 * scatter < float(np.median(halves)) < 2.0 * scatter


# ----------------------------------------------------------------------------- log columns


def run_columns(n: int = 1500) -> dict[str, np.ndarray]:
    t = np.arange(n) * PERIOD_S
    signal = 0.01 * np.sin(t)
    return {
        "time_s": t,
        "goal_rad": signal.copy(),
        "motor_angle_rad": signal,
        "link_angle_rad": signal,
        "motor_velocity_rad_s": 0.01 * np.cos(t),
        "motor_current_a": np.zeros(n),
        "torque_enabled": np.concatenate([[0.0], np.ones(n - 1)]),
    }


def test_log_columns_take_the_longest_stretch_with_torque_and_goals() -> None:
    columns = run_columns()
    columns["goal_rad"][500] = math.nan  # a tick that sent nothing: the last goal holds
    columns["torque_enabled"][1400:] = 0.0  # torque off at the end
    log = JointLog.from_log_columns(columns)
    # row 0 (torque switched on after it) .. row 1398 (its tick ends at 1399, torque on)
    assert log.time_s[0] == 0.0 and len(log) == 1400
    assert log.goal_rad[500] == columns["goal_rad"][499]


def test_log_columns_skip_past_a_gap_in_time() -> None:
    columns = run_columns()
    for name in columns:
        columns[name] = np.delete(columns[name], 300)  # a skipped tick
    log = JointLog.from_log_columns(columns)
    assert log.time_s[0] == pytest.approx(301 * PERIOD_S)
    assert np.allclose(np.diff(log.time_s), PERIOD_S)


def test_log_columns_of_a_named_joint_and_the_errors() -> None:
    columns = {
        (name if name == "time_s" else f"{name}[hip]"): value
        for name, value in run_columns().items()
    }
    assert len(JointLog.from_log_columns(columns, "hip")) == 1500
    with pytest.raises(LogFormatError, match=r"no column 'goal_rad\[knee\]'"):
        JointLog.from_log_columns(columns, "knee")
    short = {k: v[:500] for k, v in run_columns().items()}
    with pytest.raises(LogFormatError, match="at least"):
        JointLog.from_log_columns(short)


def test_identify_refuses_a_short_log() -> None:
    zeros = np.zeros(200)
    log = JointLog(np.arange(200) * PERIOD_S, zeros, zeros, zeros, zeros, zeros)
    with pytest.raises(LogFormatError, match="at least"):
        identify([log], KNOWN)
