"""Closed-form leg IK checked by forward kinematics on an independent pinocchio model.

The pinocchio model is built here, joint by joint, from the DYROS-JET URDF's leg joint
placements and axes (DYROS-JET URDF, psh117/dyros_jet, BSD-2-Clause (c) 2017 Suhan Park):

    L_HipYaw (0, 0.105, -0.1119) axis (0,0,-1); L_HipRoll (0,0,0) axis (1,0,0);
    L_HipPitch (0,0,0) axis (0,1,0); L_KneePitch (0.1515, 0, -0.339) axis (0,1,0);
    L_AnklePitch (0.06, 0, -0.368) axis (0,1,0); L_AnkleRoll (0,0,0) axis (1,0,0);
    right leg: hip at (0, -0.105, -0.1119), pitch axes (0,-1,0), yaw (0,0,-1), rolls (1,0,0);
    every origin rpy = 0; a floating base (the URDF's `virtual` joint) carries the pelvis.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from controller.walking import (
    LegGeometry,
    LegIkError,
    LegsGeometry,
    Side,
    StepTiming,
    WalkingPattern,
    leg_inverse_kinematics,
    straight_walk_plan,
    yaw_rotation,
)
from controller.walking.footsteps import Footstep, FootstepPlan

NAMES = ("HipYaw", "HipRoll", "HipPitch", "KneePitch", "AnklePitch", "AnkleRoll")
URDF_LEGS = {
    "L": (
        (0.0, 0.105, -0.1119),
        [(0, 0, -1), (1, 0, 0), (0, 1, 0), (0, 1, 0), (0, 1, 0), (1, 0, 0)],
    ),
    "R": (
        (0.0, -0.105, -0.1119),
        [(0, 0, -1), (1, 0, 0), (0, -1, 0), (0, -1, 0), (0, -1, 0), (1, 0, 0)],
    ),
}
URDF_OFFSETS = [None, (0, 0, 0), (0, 0, 0), (0.1515, 0, -0.339), (0.06, 0, -0.368), (0, 0, 0)]


def build_legs_model(
    knee_offset=(0.1515, 0.0, -0.339), roll_offset=(0.0, 0.0, 0.0), knee_rotation=None
) -> pin.Model:
    knee_rotation = np.eye(3) if knee_rotation is None else knee_rotation
    model = pin.Model()
    root = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "virtual")
    for prefix, (hip, axes) in URDF_LEGS.items():
        parent = root
        for index, (name, axis) in enumerate(zip(NAMES, axes, strict=True)):
            offset = hip if index == 0 else URDF_OFFSETS[index]
            rotation = np.eye(3)
            if index == 3:
                offset, rotation = knee_offset, knee_rotation
            if index == 1:
                offset = roll_offset
            parent = model.addJoint(
                parent,
                pin.JointModelRevoluteUnaligned(np.array(axis, dtype=float)),
                pin.SE3(rotation, np.array(offset, dtype=float)),
                f"{prefix}_{name}",
            )
        model.addFrame(
            pin.Frame(f"{prefix}_foot", parent, pin.SE3.Identity(), pin.FrameType.OP_FRAME)
        )
    return model


MODEL = build_legs_model()
LEFT_NAMES = [f"L_{n}" for n in NAMES]
RIGHT_NAMES = [f"R_{n}" for n in NAMES]


def forward(q: np.ndarray) -> tuple[pin.SE3, pin.SE3, pin.SE3]:
    data = MODEL.createData()
    pin.framesForwardKinematics(MODEL, data, q)
    return (data.oMi[1], data.oMf[MODEL.getFrameId("L_foot")], data.oMf[MODEL.getFrameId("R_foot")])


def configuration(pelvis: pin.SE3, joints: np.ndarray) -> np.ndarray:
    q = pin.neutral(MODEL)
    q[:7] = pin.SE3ToXYZQUAT(pelvis)
    q[7:] = joints
    return q


def test_geometry_from_the_pinocchio_model_equals_the_figures():
    assert LegGeometry.from_pinocchio(MODEL, LEFT_NAMES) == LegGeometry.dyros_jet(Side.LEFT)
    assert LegGeometry.from_pinocchio(MODEL, RIGHT_NAMES) == LegGeometry.dyros_jet(Side.RIGHT)
    # Knee straight at q4 = -(a(t0) - a(s0)): the lab's 14.82 deg = 24.08 - 9.26 deg offsets.
    geometry = LegGeometry.dyros_jet(Side.LEFT)
    assert math.degrees(geometry.knee_offset_rad) == pytest.approx(
        math.degrees(math.atan2(0.1515, 0.339) - math.atan2(0.06, 0.368))
    )
    assert math.degrees(geometry.knee_offset_rad) == pytest.approx(14.82, abs=0.01)


@pytest.mark.parametrize(
    ("model", "message"),
    [
        (build_legs_model(knee_offset=(0.1515, 0.01, -0.339)), "not offset|pitch|plane"),
        (build_legs_model(roll_offset=(0.0, 0.0, 0.02)), "intersecting"),
        (build_legs_model(knee_rotation=pin.rpy.rpyToMatrix(0.0, 0.1, 0.0)), "rotated"),
    ],
)
def test_from_pinocchio_refuses_a_leg_the_closed_form_cannot_solve(model, message):
    with pytest.raises(LegIkError, match=message):
        LegGeometry.from_pinocchio(model, LEFT_NAMES)


def test_from_pinocchio_refuses_joints_out_of_chain_order():
    with pytest.raises(LegIkError, match="child"):
        LegGeometry.from_pinocchio(
            MODEL, [LEFT_NAMES[0], LEFT_NAMES[2], *LEFT_NAMES[1:2], *LEFT_NAMES[3:]]
        )
    with pytest.raises(LegIkError, match="not in the model"):
        LegGeometry.from_pinocchio(MODEL, ["L_Nope", *LEFT_NAMES[1:]])


def test_zero_pose_gives_zero_angles():
    pelvis, left, right = forward(configuration(pin.SE3.Identity(), np.zeros(12)))
    for geometry, foot in (
        (LegGeometry.dyros_jet(Side.LEFT), left),
        (LegGeometry.dyros_jet(Side.RIGHT), right),
    ):
        angles = leg_inverse_kinematics(
            geometry, pelvis.translation, pelvis.rotation, foot.translation, foot.rotation
        )
        assert np.abs(angles).max() < 1e-12


def test_recovers_random_joint_angles_of_the_solved_branch():
    """Angles in the branch the closed form returns (knee bent forward, |hip roll| and
    |ankle roll| < 90 deg, the hip above the ankle in the ankle-pitch joint's frame, which
    pinocchio tells here): FK then IK gives them back."""
    rng = np.random.default_rng(7)
    geometry = LegsGeometry.dyros_jet()
    data = MODEL.createData()
    ankle_pitch = [MODEL.getJointId("L_AnklePitch"), MODEL.getJointId("R_AnklePitch")]
    hip = [MODEL.getJointId("L_HipYaw"), MODEL.getJointId("R_HipYaw")]
    worst, tried = 0.0, 0
    for _ in range(500):
        pelvis = pin.SE3(pin.exp3(rng.uniform(-0.4, 0.4, 3)), rng.uniform(-0.5, 0.5, 3))
        physical = np.column_stack(
            [
                rng.uniform(-0.6, 0.6, 2),
                rng.uniform(-0.5, 0.5, 2),
                rng.uniform(-1.2, 0.6, 2),
                rng.uniform(-0.2, 1.6, 2),
                rng.uniform(-1.2, 1.2, 2),
                rng.uniform(-0.5, 0.5, 2),
            ]
        )
        joints = np.concatenate(
            [physical[0] * geometry.left.axis_signs, physical[1] * geometry.right.axis_signs]
        )
        q = configuration(pelvis, joints)
        pin.forwardKinematics(MODEL, data, q)
        if any(
            (data.oMi[a].actInv(data.oMi[h].translation))[2] <= 0
            for a, h in zip(ankle_pitch, hip, strict=True)
        ):
            continue  # the other ankle branch
        tried += 1
        base, left, right = forward(q)
        solved = np.concatenate(
            [
                leg_inverse_kinematics(
                    geometry.left, base.translation, base.rotation, left.translation, left.rotation
                ),
                leg_inverse_kinematics(
                    geometry.right,
                    base.translation,
                    base.rotation,
                    right.translation,
                    right.rotation,
                ),
            ]
        )
        worst = max(worst, np.abs(solved - joints).max())
    assert tried > 300
    assert worst < 1e-9


def test_any_reachable_pose_is_solved_exactly():
    """Wide random angles (other branches too): the solution may differ, its FK may not."""
    rng = np.random.default_rng(3)
    geometry = LegGeometry.dyros_jet(Side.LEFT)
    worst_position = worst_rotation = 0.0
    for _ in range(500):
        joints = np.zeros(12)
        joints[:6] = [
            rng.uniform(-3, 3),
            rng.uniform(-1.4, 1.4),
            rng.uniform(-3, 3),
            rng.uniform(-0.25, 2.8),
            rng.uniform(-3, 3),
            rng.uniform(-3, 3),
        ]
        pelvis = pin.SE3(pin.exp3(rng.uniform(-1, 1, 3)), rng.uniform(-1, 1, 3))
        base, target, _ = forward(configuration(pelvis, joints))
        solved = leg_inverse_kinematics(
            geometry, base.translation, base.rotation, target.translation, target.rotation
        )
        joints[:6] = solved
        _, reached, _ = forward(configuration(pelvis, joints))
        worst_position = max(
            worst_position, np.linalg.norm(reached.translation - target.translation)
        )
        worst_rotation = max(
            worst_rotation, np.linalg.norm(pin.log3(reached.rotation.T @ target.rotation))
        )
    assert worst_position < 1e-12 and worst_rotation < 1e-12


def test_out_of_reach_raises():
    geometry = LegGeometry.dyros_jet(Side.LEFT)
    with pytest.raises(LegIkError, match="out of reach"):
        leg_inverse_kinematics(
            geometry, np.array([0, 0, 1.0]), np.eye(3), np.array([0, 0.105, 0.0]), np.eye(3)
        )


def _fk_errors(pattern: WalkingPattern) -> tuple[float, float]:
    worst_position = worst_rotation = 0.0
    data = MODEL.createData()
    left_id, right_id = MODEL.getFrameId("L_foot"), MODEL.getFrameId("R_foot")
    for k in range(pattern.n_ticks):
        pelvis = pin.SE3(yaw_rotation(pattern.pelvis_yaw_rad[k]), pattern.pelvis_position_m[k])
        pin.framesForwardKinematics(MODEL, data, configuration(pelvis, pattern.joint_angles_rad[k]))
        for side, frame in ((Side.LEFT, left_id), (Side.RIGHT, right_id)):
            reached = data.oMf[frame]
            wanted_rotation = yaw_rotation(pattern.foot_yaw_rad[k, side.index])
            worst_position = max(
                worst_position,
                np.linalg.norm(reached.translation - pattern.foot_position_m[k, side.index]),
            )
            worst_rotation = max(
                worst_rotation, np.linalg.norm(pin.log3(reached.rotation.T @ wanted_rotation))
            )
    return worst_position, worst_rotation


@pytest.mark.parametrize(
    "timing",
    [StepTiming(0.8, 3.2, 1.6, 1.0), StepTiming(0.8, 0.3, 1.6, 1.0)],
    ids=["slow", "dynamic"],
)
def test_ik_over_the_whole_walking_trajectory_by_forward_kinematics(timing):
    pattern = WalkingPattern(straight_walk_plan(6, 0.2, timing), legs=LegsGeometry.dyros_jet())
    position, rotation = _fk_errors(pattern)
    assert position < 1e-6 and rotation < 1e-6  # measured ~1e-16
    # Feet flat, pelvis upright: the pitch joints of each leg sum to zero (hip + knee + ankle).
    assert np.abs(pattern.joint_angles_rad[:, 2:5].sum(axis=1)).max() < 1e-12
    assert np.abs(pattern.joint_angles_rad[:, 8:11].sum(axis=1)).max() < 1e-12


def test_ik_on_a_turning_walk_by_forward_kinematics():
    timing = StepTiming(0.8, 0.3, 1.6, 1.0)
    w = 0.127794
    steps = []
    for i, side in enumerate([Side.RIGHT, Side.LEFT, Side.RIGHT, Side.LEFT]):
        yaw = 0.15 * (i + 1)
        centre = np.array([0.15 * (i + 1), 0.03 * (i + 1)])
        lateral = side.lateral_sign * w * np.array([-math.sin(yaw), math.cos(yaw)])
        steps.append(Footstep(side, *(centre + lateral), yaw_rad=yaw))
    plan = FootstepPlan(
        Footstep(Side.LEFT, 0, w), Footstep(Side.RIGHT, 0, -w), tuple(steps), timing
    )
    pattern = WalkingPattern(plan, legs=LegsGeometry.dyros_jet())
    assert np.abs(pattern.joint_angles_rad[:, [0, 6]]).max() > 0.05  # the hips do yaw
    position, rotation = _fk_errors(pattern)
    assert position < 1e-6 and rotation < 1e-6
