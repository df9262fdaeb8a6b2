"""The lab's walking scheme on a run (hil/experiments/walking_scheme.py): which terms each
controller gets, the CoM feedback's correction by hand, and the loop following (and logging) the
corrected reference."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from controller.humanoid import HumanoidLegGravity, SupportState
from controller.walking import CenterOfMassMeasurement, yaw_rotation
from hil.config import load_config
from hil.experiments import IMPACT, STAND, WALK_SLOW
from hil.experiments.legs import leg_model
from hil.experiments.walking_scheme import LabWalkingScheme
from hil.output.records import RunEntry, RunResult
from hil.vocabulary import ControllerChoice, ControllerKind, RunEnding, Termination
from tests.support.rig import run_in_process

PATTERN = WALK_SLOW.pattern
TICKS = (0, 400, 900, 1000, 1100)  # the rest, the weight shift, the first single support


@pytest.fixture(scope="module")
def config():
    return load_config(robot="dyros-jet")


def test_the_default_controller_gets_the_position_mode_terms_every_controller_the_feedback(
    config,
) -> None:
    pid = WALK_SLOW.reference_feedback(config, ControllerChoice(ControllerKind.PID))
    assert pid.com_feedback is not None and pid.deflection is not None
    assert pid.hip_roll is not None
    assert "deflection model" in pid.describe() and "measured-pelvis" in pid.describe()
    for kind in (ControllerKind.GC, ControllerKind.GC_LQR, ControllerKind.GC_LQR_DOB):
        scheme = WALK_SLOW.reference_feedback(config, ControllerChoice(kind, 0.2))
        assert scheme.com_feedback is not None
        assert scheme.deflection is None and scheme.hip_roll is None
    off = config.changed("walking", com_feedback_gain=0.0)
    assert WALK_SLOW.reference_feedback(off, ControllerChoice(ControllerKind.GC)) is None
    nothing = off.changed("walking", deflection_model=False, support_hip_roll_offsets=False)
    assert WALK_SLOW.reference_feedback(nothing, ControllerChoice(ControllerKind.PID)) is None
    # the other experiments have none
    assert STAND.reference_feedback(config, ControllerChoice(ControllerKind.PID)) is None
    assert IMPACT.reference_feedback(load_config(), ControllerChoice(ControllerKind.PID)) is None


@pytest.mark.parametrize("measured_from", list(CenterOfMassMeasurement))
def test_a_robot_on_its_plan_gets_the_plan(config, measured_from) -> None:
    """Links exactly at the planned angles: the measured CoM is the planned one (the pattern
    solves its pelvis for it, 1e-7 m), the correction stays ~0 and so does the change."""
    walking = config.changed("walking", com_measured_from=str(measured_from))
    scheme = LabWalkingScheme.for_run(PATTERN, walking, ControllerChoice(ControllerKind.GC))
    for tick in TICKS:
        planned = PATTERN.joint_angles_rad[tick]
        reference = scheme.reference(tick * PATTERN.dt_s, planned, planned)
        assert np.abs(reference - planned).max() < 1e-5
    assert np.abs(scheme.correction_m).max() < 1e-6


def test_the_correction_is_kp_times_the_measured_com_error(config) -> None:
    """One tick with the knees bent 3 deg more than planned: correction = kp (c_desired -
    c_measured), c_measured the measured legs' CoM hung from the plan's pelvis (the lab's
    master); the new reference puts both ankles where the plan does, with the pelvis moved by
    the correction."""
    master = config.changed("walking", com_feedback_gain=0.15, com_measured_from="commanded-pelvis")
    scheme = LabWalkingScheme.for_run(PATTERN, master, ControllerChoice(ControllerKind.GC))
    model = leg_model()
    tick = 900
    planned = PATTERN.joint_angles_rad[tick]
    links = planned.copy()
    links[[3, 9]] += np.radians([3.0, -3.0])
    pelvis = PATTERN.pelvis_position_m[tick]
    rotation = yaw_rotation(PATTERN.pelvis_yaw_rad[tick])
    measured = model.centre_of_mass(model.configuration(links, pelvis, rotation))
    error = PATTERN.com_position_m[tick][:2] - measured[:2]
    assert np.abs(error).max() > 0.002  # the bent knees moved the CoM
    reference = scheme.reference(tick * PATTERN.dt_s, planned, links)
    assert scheme.correction_m == pytest.approx(0.15 * error, abs=1e-12)
    moved = pelvis + np.array([*scheme.correction_m, 0.0])
    model.update_kinematics(model.configuration(reference, moved, rotation))
    for side in (0, 1):
        ankle = model.ft_sensor_placement(side).translation  # the ankle-roll frame
        assert ankle == pytest.approx(PATTERN.foot_position_m[tick, side], abs=1e-6)


def test_the_2018_form_cancels_the_sway_and_keeps_the_legs_shape(config) -> None:
    """The lab's 2018 form (the default): pelvis = pelvis measured + kp (c_desired -
    c_measured), both with the stance sole flat. The whole robot swayed sideways on its stance
    ankle (the ankle roll 20 mrad off, nothing else): at kp = 1 the sway cancels and the
    pelvis stays where the plan's shape puts it (the legs' shape is the plan's but for the
    ankle, so nearly the plan's pelvis); at kp = 0.9 a tenth of the measured CoM error is
    added to the command, by hand."""
    from hil.experiments.legs import anchor_feet, placed_configuration

    tick = 1000  # the first single support, left stance
    planned = PATTERN.joint_angles_rad[tick]
    swayed = planned.copy()
    swayed[5] += 0.02  # the left (stance) ankle roll
    model = leg_model()
    q = placed_configuration(model, swayed, int(anchor_feet(PATTERN)[tick]), PATTERN, tick)
    pelvis, com = q[:3].copy(), model.centre_of_mass(q)
    desired, plan_pelvis = PATTERN.com_position_m[tick], PATTERN.pelvis_position_m[tick]
    assert abs(com[1] - desired[1]) > 0.01  # the sway moved the CoM by centimetres
    for kp in (1.0, 0.9):
        walking = config.changed("walking", com_feedback_gain=kp)
        scheme = LabWalkingScheme.for_run(PATTERN, walking, ControllerChoice(ControllerKind.GC))
        scheme.reference(tick * PATTERN.dt_s, planned, swayed)
        expected = pelvis[:2] + kp * (desired[:2] - com[:2]) - plan_pelvis[:2]
        assert scheme.correction_m == pytest.approx(expected, abs=1e-12)
        if kp == 1.0:  # the sway is gone: what is left is the ankle's share of the shape
            assert np.abs(scheme.correction_m).max() < 0.2 * abs(com[1] - desired[1])


def test_the_feedback_measures_by_the_motors_where_configured(config) -> None:
    """com_feedback_angles = "motor" (the lab's code): the motors' angles in place of the
    links'; a motor bent off the plan moves the correction, a link bent off it does not (and
    the other way round by default)."""
    tick = 1000
    planned = PATTERN.joint_angles_rad[tick]
    bent = planned.copy()
    bent[[3, 9]] += np.radians([3.0, -3.0])
    motors = config.changed("walking", com_feedback_angles="motor")
    for walking, links, motor, moved in (
        (motors, bent, planned, False),
        (motors, planned, bent, True),
        (config, planned, bent, False),
        (config, bent, planned, True),
    ):
        scheme = LabWalkingScheme.for_run(PATTERN, walking, ControllerChoice(ControllerKind.GC))
        scheme.reference(tick * PATTERN.dt_s, planned, links, motor)
        assert bool(np.abs(scheme.correction_m).max() > 1e-4) is moved  # 0.5 mm against 4e-8


def test_the_loop_follows_and_logs_the_corrected_reference(config, tmp_path: Path) -> None:
    """pid, the CoM feedback off: the reference the loop logged (and sent: pid's goal is its
    reference) is the plan plus the deflection model of (5)'s torque at the planned posture
    (double support in the rest; the hip-roll offsets start with the first single support)."""
    walking = config.changed("walking", com_feedback_gain=0.0)
    result, run = run_in_process(walking, WALK_SLOW, "pid", tmp_path, duration_s=0.5)
    assert result.ok, result.ending
    assert "deflection model" in run.summary["reference_feedback"]
    names = walking.joint_names
    logged = np.column_stack([run.columns[f"reference_rad[{n}]"] for n in names])
    goals = np.column_stack([run.columns[f"goal_rad[{n}]"] for n in names])
    started = run.columns["phase"] == "experiment"
    ticks = np.rint((run.data.time_s[started] - run.data.experiment_start_s) / PATTERN.dt_s)
    gravity = HumanoidLegGravity(leg_model(), SupportState.DOUBLE)
    scheme = LabWalkingScheme.for_run(PATTERN, walking, ControllerChoice(ControllerKind.PID))
    planned = PATTERN.joint_angles_rad[ticks.astype(int)]
    expected = planned + [scheme.deflection.offsets(gravity.gravity_torque(q)) for q in planned]
    assert np.abs(logged[started] - expected).max() < 1e-9
    assert np.abs(expected - planned)[:, [3, 9]].min() > 0.01  # the knees: ~11 mrad
    assert np.abs(goals[started][1:] - logged[started][1:]).max() < 1e-9


def _entry(kind: ControllerKind, steps: int, fell: bool, stopped: float | None) -> RunEntry:
    metrics = {
        "steps_completed": steps,
        "fell": fell,
        "fell_at_s": 11.2 if fell else None,
        "stopped_at_s": stopped,
        "zmp_rms_error_m": 0.03,
    }
    ending = RunEnding(Termination.COMPLETED if stopped is None else Termination.SAFETY_STOP)
    choice = ControllerChoice(kind, 0.2)
    return RunEntry("walk-slow", choice, RunResult(Path("."), ending, metrics))


def test_the_slow_walk_is_checked_for_every_controller() -> None:
    """Fig. 7(a) walks all four controllers slowly: one relation each (the default controller
    named so); a fall, a safety stop or a missing step is not a walk."""
    entries = [
        _entry(ControllerKind.PID, 2, True, 15.1),
        _entry(ControllerKind.GC, 4, False, None),
        _entry(ControllerKind.GC_LQR, 4, False, 3.0),
        _entry(ControllerKind.GC_LQR_DOB, 3, False, None),
    ]
    verdicts = {
        r.claim: r.holds
        for r in WALK_SLOW.relations(entries)
        if "completes the slow walk" in r.claim
    }
    assert verdicts == {
        "the default controller (pid) completes the slow walk (every step, no fall, no safety "
        "stop)": False,
        "GC completes the slow walk (every step, no fall, no safety stop)": True,
        "GC+LQR completes the slow walk (every step, no fall, no safety stop)": False,
        "GC+LQR+DOB completes the slow walk (every step, no fall, no safety stop)": False,
    }
