"""The walking experiments (hil/experiments/walking.py): their references, their world, and their
metrics, checked against analysis (forward kinematics, a synthetic walk whose ZMP is known)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from controller.humanoid import (
    LEG_JOINT_NAMES,
    WALKING_READY_LEG_ANGLES_RAD,
    LegModel,
    SupportState,
)
from controller.walking import SegmentKind, yaw_rotation
from controller.walking.dyros_jet_figures import FOOT_LENGTH_M, FOOT_WIDTH_M
from drivers.joint_bus import wrench_keys
from hil.config import load_config, robot_description_text
from hil.experiments import STEP_ON_OBJECT, WALK_DYNAMIC
from hil.experiments.walking import OBJECT_FOOTSTEP, OBJECT_HEIGHT_M, WalkingExperiment
from hil.output.rundir import RunData
from hil.robots import EXPERIMENTS, robot_of_experiment
from hil.wiring.emulation import emulator_spec, spec_from_json, spec_to_json

WALKS = ("walk-slow", "walk-dynamic", "step-on-object")


@pytest.fixture(scope="module")
def config():
    return load_config(robot="dyros-jet")


@pytest.fixture(scope="module")
def model(config) -> LegModel:
    return LegModel(robot_description_text(config))


def test_registered_for_dyros_jet() -> None:
    for name in WALKS:
        assert isinstance(EXPERIMENTS[name], WalkingExperiment)
        assert robot_of_experiment(name) == "dyros-jet"
    slow, dynamic = EXPERIMENTS["walk-slow"], EXPERIMENTS["walk-dynamic"]
    assert (slow.single_support_s, slow.double_support_s) == (0.8, 3.2)  # Sec. IV-C
    assert (dynamic.single_support_s, dynamic.double_support_s) == (0.8, 0.3)
    # rest 1.6 + 4 x (DS + SS) + final DS + rest 0.5
    assert slow.duration_s == pytest.approx(1.6 + 4 * 4.0 + 3.2 + 0.5)


@pytest.mark.parametrize("name", WALKS)
def test_references_are_ik_consistent_and_within_the_joint_limits(name, config, model) -> None:
    """Forward kinematics of the reference (at the pattern's pelvis) puts every ankle where the
    pattern planned it; tick 0 is the walking-ready posture the robot stands in at power-on."""
    experiment = EXPERIMENTS[name]
    pattern = experiment.pattern
    angles = pattern.joint_angles_rad
    assert np.abs(angles[0] - np.asarray(WALKING_READY_LEG_ANGLES_RAD)).max() < 1e-6
    worst = 0.0
    for k in range(0, pattern.n_ticks, 17):
        q = model.configuration(
            angles[k], pattern.pelvis_position_m[k], yaw_rotation(pattern.pelvis_yaw_rad[k])
        )
        model.update_kinematics(q)
        for side in (0, 1):
            ankle = model.ft_sensor_placement(side).translation  # the ankle-roll frame
            worst = max(worst, np.abs(ankle - pattern.foot_position_m[k, side]).max())
    assert worst < 1e-6
    low, high = experiment.reference_range(12)
    for j, joint in enumerate(config.joints):
        assert joint.min_angle_rad + 0.05 < low[j] <= high[j] < joint.max_angle_rad - 0.05, (
            joint.name,
            low[j],
            high[j],
        )
    # the loop's table is the pattern, read on the loop's grid
    table = experiment.reference_table(0.005, 50, 12)
    assert np.array_equal(table, angles[:50])


def test_support_and_kdist_follow_the_phase() -> None:
    experiment = WALK_DYNAMIC
    timeline = experiment.pattern.timeline
    dt = experiment.pattern.dt_s
    first_single = next(s for s in timeline.segments if s.kind is SegmentKind.SINGLE_SUPPORT)
    assert experiment.support(0.0) is SupportState.DOUBLE
    middle = (first_single.start_tick + first_single.n_ticks // 2) * dt
    assert experiment.support(middle) is SupportState.LEFT  # the right foot swings first
    kdist = experiment.kdist_at(middle, 0.2)
    assert np.allclose(kdist, 0.2)  # mid-swing: both legs at the stance gain
    touchdown = first_single.end_tick * dt
    kdist = experiment.kdist_at(touchdown, 0.2)
    assert np.allclose(kdist[6:], 1.0) and np.allclose(kdist[:6], 0.2)  # the landing (right) leg


def test_the_planned_motion_is_the_patterns(model) -> None:
    """What the walk hands the controller each tick (controller.PlannedMotion): the pattern's
    joint increments and their velocity increments, its CoM acceleration, and (7)'s mu of its
    ZMP between the feet's ZMP points: 0.5 in the rest, 0 where the reference reaches the
    left stance point at the end of the first double support, 0.5 on the lab split's middle
    hold after the right foot lands."""
    experiment = WALK_DYNAMIC
    pattern = experiment.pattern
    angles, dt = pattern.joint_angles_rad, pattern.dt_s
    timeline = pattern.timeline
    first_double, first_single, after = timeline.segments[1:4]
    for tick in (0, 400, first_single.start_tick + 30, after.start_tick + 30):
        motion = experiment.planned_motion(tick * dt)
        increment = angles[tick] - angles[max(tick - 1, 0)]
        before = angles[max(tick - 1, 0)] - angles[max(tick - 2, 0)]
        assert np.array_equal(motion.reference_increment_rad, increment)
        assert np.allclose(motion.reference_velocity_increment_rad_s, (increment - before) / dt)
        assert np.array_equal(motion.com_acceleration_mps2, pattern.com_acceleration_mps2[tick])
    assert experiment.planned_motion(1.0).support_split == pytest.approx(0.5)
    last = experiment.planned_motion((first_double.end_tick - 1) * dt)
    assert last.support_split == pytest.approx(0.0, abs=1e-12)
    hold = experiment.planned_motion((after.start_tick + 30) * dt)
    assert hold.support_split == pytest.approx(0.5, abs=1e-12)


def test_the_object_lies_under_its_footstep_and_nowhere_else(config) -> None:
    (box,) = STEP_ON_OBJECT.world.floor_objects
    assert box.height_m == OBJECT_HEIGHT_M
    x0, x1 = box.centre_m[0] - box.size_m[0] / 2, box.centre_m[0] + box.size_m[0] / 2
    y0, y1 = box.centre_m[1] - box.size_m[1] / 2, box.centre_m[1] + box.size_m[1] / 2
    plan = STEP_ON_OBJECT.plan
    placements = [plan.initial_left, plan.initial_right, *plan.footsteps]
    for index, step in enumerate(placements):
        # the sole: FOOT_LENGTH_M x FOOT_WIDTH_M, its centre 0.01 m ahead of the ankle
        sx0, sx1 = step.x_m + 0.01 - FOOT_LENGTH_M / 2, step.x_m + 0.01 + FOOT_LENGTH_M / 2
        sy0, sy1 = step.y_m - FOOT_WIDTH_M / 2, step.y_m + FOOT_WIDTH_M / 2
        if index == 2 + OBJECT_FOOTSTEP:
            assert x0 < sx0 and sx1 < x1 and y0 < sy0 and sy1 < y1  # the whole sole on the box
        else:
            assert sx1 < x0 or sx0 > x1 or sy1 < y0 or sy0 > y1, f"placement {index} on the box"
    # the plan does not know it: its feet stay at the ground's height
    assert np.allclose(STEP_ON_OBJECT.pattern.foot_position_m[:, :, 2].min(), 0.105)
    spec = emulator_spec(config, experiment=STEP_ON_OBJECT)
    assert spec.humanoid is not None
    (floor_box,) = spec.humanoid.floor_boxes
    assert floor_box.centre_m == box.centre_m and floor_box.size_m == box.size_m
    assert spec_from_json(spec_to_json(spec)).humanoid.floor_boxes == (floor_box,)
    assert emulator_spec(config, experiment=WALK_DYNAMIC).humanoid.floor_boxes == ()


@pytest.mark.parametrize(("name", "lateral_m"), [("walk-slow", 0.01), ("walk-dynamic", 0.02)])
def test_the_pattern_walks_a_rigid_robot(name, lateral_m, model) -> None:
    """The pattern's ZMP on the rigid multibody model (CoM and centroidal angular momentum of
    the URDF robot along the pattern, (x, y) = CoM - (z_c ddCoM_xy -+ dL_yx / m) / (ddz_c + g))
    stays near the reference: the cart-table ignores the swing leg's momentum, not more. So the
    errors measured on the flexible robot are the plant's, not the generator's."""
    pattern = EXPERIMENTS[name].pattern
    dt, n = pattern.dt_s, pattern.n_ticks
    com = np.empty((n, 3))
    momentum = np.empty((n, 3))
    previous = None
    for k in range(n):
        q = model.configuration(
            pattern.joint_angles_rad[k],
            pattern.pelvis_position_m[k],
            yaw_rotation(pattern.pelvis_yaw_rad[k]),
        )
        v = (
            np.zeros(model.nv)
            if previous is None
            else pin.difference(model.model, previous, q) / dt
        )
        pin.computeCentroidalMomentum(model.model, model.data, q, v)
        com[k], momentum[k] = model.data.com[0], model.data.hg.angular
        previous = q
    acc = np.gradient(np.gradient(com, dt, axis=0), dt, axis=0)
    rate = np.gradient(momentum, dt, axis=0)
    mass, g = model.total_mass_kg, 9.81
    vertical = acc[:, 2] + g
    zmp = np.column_stack(
        [
            com[:, 0] - (com[:, 2] * acc[:, 0] + rate[:, 1] / mass) / vertical,
            com[:, 1] - (com[:, 2] * acc[:, 1] - rate[:, 0] / mass) / vertical,
        ]
    )
    error = (zmp - pattern.zmp_reference_m)[5:-5]
    assert np.abs(error[:, 1]).max() < lateral_m
    assert np.sqrt(np.mean(error[:, 0] ** 2)) < 0.02  # sagittal: the swing leg's momentum


def _synthetic_walk(
    experiment: WalkingExperiment, model: LegModel, unloaded_from_s: float | None = None
) -> RunData:
    """A log of the perfect walk: link angles = the reference; the feet's sensors read forces
    whose ZMP is the desired one (each foot's vertical share from where the ZMP lies between the
    feet; the stance foot carries all in single support); from `unloaded_from_s` the feet read
    nothing (the robot airborne: fallen)."""
    pattern = experiment.pattern
    n = pattern.n_ticks
    weight = model.total_mass_kg * 9.81
    columns: dict[str, np.ndarray] = {"time_s": pattern.time_s.copy()}
    for j, joint in enumerate(LEG_JOINT_NAMES):
        columns[f"link_angle_rad[{joint}]"] = pattern.joint_angles_rad[:, j].copy()
    wrenches = np.zeros((2, n, 6))
    for k in range(n):
        q = model.configuration(
            pattern.joint_angles_rad[k],
            pattern.pelvis_position_m[k],
            yaw_rotation(pattern.pelvis_yaw_rad[k]),
        )
        model.update_kinematics(q)
        phase = pattern.timeline.phase(k)
        zmp = np.array([*pattern.zmp_reference_m[k], 0.0])
        if phase.support.value == "left":
            shares = (1.0, 0.0)
        elif phase.support.value == "right":
            shares = (0.0, 1.0)
        else:
            left_y, right_y = pattern.foot_position_m[k, 0, 1], pattern.foot_position_m[k, 1, 1]
            share = float(np.clip((zmp[1] - right_y) / (left_y - right_y), 0.0, 1.0))
            shares = (share, 1.0 - share)
        for side in (0, 1):
            sensor = model.ft_sensor_placement(side)
            force = np.array([0.0, 0.0, shares[side] * weight])
            torque = np.cross(zmp - sensor.translation, force)  # the force acts at the ZMP
            wrenches[side, k] = np.concatenate(
                [sensor.rotation.T @ force, sensor.rotation.T @ torque]
            )
    if unloaded_from_s is not None:
        wrenches[:, pattern.time_s >= unloaded_from_s] = 0.0
    for side, foot in enumerate(("left_foot", "right_foot")):
        for axis, key in enumerate(wrench_keys(foot)):
            columns[key] = wrenches[side, :, axis]
    return RunData(Path("."), columns, {}, {"experiment_start_s": 0.0}, (), LEG_JOINT_NAMES)


def test_metrics_of_a_perfect_walk(model) -> None:
    metrics = WALK_DYNAMIC.metrics(_synthetic_walk(WALK_DYNAMIC, model))
    assert metrics["steps_completed"] == WALK_DYNAMIC.n_steps
    assert metrics["fell"] is False and metrics["stopped_early"] is False
    for key in ("zmp_max_error_m", "zmp_max_error_lateral_m", "zmp_max_error_sagittal_m"):
        assert metrics[key] < 1e-5, key
    # the desired ZMP never comes within EDGE_MARGIN_M (1 cm) of the soles' edge
    assert metrics["zmp_at_edge_s"] == 0.0


def test_a_walk_that_fails_after_two_steps(model) -> None:
    """The feet unloaded from the third step's touchdown: two steps taken, then a fall."""
    timeline = WALK_DYNAMIC.pattern.timeline
    third_touchdown = timeline.touchdown_times_s[2]
    metrics = WALK_DYNAMIC.metrics(_synthetic_walk(WALK_DYNAMIC, model, third_touchdown))
    assert metrics["steps_completed"] == 2
    assert metrics["fell"] is True
    assert metrics["fell_at_s"] == pytest.approx(third_touchdown, abs=0.006)
