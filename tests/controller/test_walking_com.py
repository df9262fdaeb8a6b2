"""The pelvis solved so that a whole-robot model's CoM follows the planned CoM."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from controller.walking import (
    LegIkError,
    LegsGeometry,
    StepTiming,
    WalkingParams,
    WalkingPattern,
    straight_walk_plan,
    yaw_rotation,
)
from controller.walking.center_of_mass import PinocchioCenterOfMass

NAMES = ("HipYaw", "HipRoll", "HipPitch", "KneePitch", "AnklePitch", "AnkleRoll")
AXES = {
    "L": [(0, 0, -1), (1, 0, 0), (0, 1, 0), (0, 1, 0), (0, 1, 0), (1, 0, 0)],
    "R": [(0, 0, -1), (1, 0, 0), (0, -1, 0), (0, -1, 0), (0, -1, 0), (1, 0, 0)],
}
OFFSETS = [None, (0, 0, 0), (0, 0, 0), (0.1515, 0, -0.339), (0.06, 0, -0.368), (0, 0, 0)]
# Link masses [kg] and CoMs [m] in the link frames: DYROS-JET URDF, psh117/dyros_jet,
# BSD-2-Clause (c) 2017 Suhan Park (left leg; the right leg mirrors y, with the URDF's thigh
# CoM x of 0.11203 instead of 0.12203).
LINKS = [
    (1.54216, (-0.02955, 0.0, 0.06943)),
    (1.16907, (0.00513, -0.00119, 0.0)),
    (3.28269, (0.12203, 0.00306, -0.23316)),
    (2.04524, (0.05276, -0.01856, -0.22635)),
    (1.18450, (-0.01035, 0.00568, 0.0)),
    (1.42541, (-0.00989, 0.0, 0.07224)),
]
BASE = (3.90994, (0.0, 0.0, 0.08027))  # base_link, same source
# A lumped stand-in for the torso and arms of this test (not a figure of the robot): the URDF's
# upper-body mass, 24.75 kg, at 0.3 m above the pelvis, 2 cm forward.
UPPER_BODY = (24.75, (0.02, 0.0, 0.30))


def _inertia(mass: float, com: tuple[float, float, float]) -> pin.Inertia:
    return pin.Inertia(mass, np.array(com, dtype=float), np.eye(3) * 1e-3)


def build_robot_model() -> pin.Model:
    model = pin.Model()
    root = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "virtual")
    model.appendBodyToJoint(root, _inertia(*BASE), pin.SE3.Identity())
    model.appendBodyToJoint(root, _inertia(*UPPER_BODY), pin.SE3.Identity())
    for prefix, hip_y in (("L", 0.105), ("R", -0.105)):
        parent = root
        for index, name in enumerate(NAMES):
            offset = (0.0, hip_y, -0.1119) if index == 0 else OFFSETS[index]
            parent = model.addJoint(
                parent,
                pin.JointModelRevoluteUnaligned(np.array(AXES[prefix][index], dtype=float)),
                pin.SE3(np.eye(3), np.array(offset, dtype=float)),
                f"{prefix}_{name}",
            )
            mass, com = LINKS[index]
            if prefix == "R":
                com = (0.11203 if index == 2 else com[0], -com[1], com[2])
            model.appendBodyToJoint(parent, _inertia(mass, com), pin.SE3.Identity())
    return model


MODEL = build_robot_model()
LEG_NAMES = [f"{p}_{n}" for p in "LR" for n in NAMES]


def test_model_mass_is_the_urdf_total():
    assert pin.computeTotalMass(MODEL) == pytest.approx(49.958, abs=0.01)


@pytest.fixture(scope="module")
def patterns():
    plan = straight_walk_plan(4, 0.2, StepTiming(0.8, 0.3, 1.6, 1.0))
    legs = LegsGeometry.dyros_jet()
    plain = WalkingPattern(plan, legs=legs)
    solved = WalkingPattern(plan, legs=legs, com_model=PinocchioCenterOfMass(MODEL, LEG_NAMES))
    return plain, solved


def test_solved_pelvis_puts_the_model_com_on_the_plan(patterns):
    plain, solved = patterns
    data = MODEL.createData()
    worst = 0.0
    for k in range(0, solved.n_ticks, 7):
        q = pin.neutral(MODEL)
        q[:7] = pin.SE3ToXYZQUAT(
            pin.SE3(yaw_rotation(solved.pelvis_yaw_rad[k]), solved.pelvis_position_m[k])
        )
        q[7:] = solved.joint_angles_rad[k]  # the legs' joints are the model's only others
        com = pin.centerOfMass(MODEL, data, q)
        worst = max(worst, np.abs(com - solved.com_position_m[k]).max())
    assert worst < 1e-6
    assert np.abs(solved.model_com_m - solved.com_position_m).max() < 1e-6


def test_pelvis_equal_to_com_would_misplace_the_model_com_by_centimetres(patterns):
    plain, solved = patterns
    shift = solved.pelvis_position_m - solved.com_position_m
    assert np.abs(shift[:, 0]).max() > 0.01  # the upper body's and thighs' CoMs lie forward
    # The shift varies with the swing leg: a constant offset would not do.
    assert np.ptp(shift[:, 1]) > 1e-3


def test_refuses_a_model_without_a_free_flyer():
    fixed = pin.Model()
    fixed.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "z")
    with pytest.raises(ValueError, match="free-flyer"):
        PinocchioCenterOfMass(fixed, LEG_NAMES)


def test_com_model_needs_the_legs_and_a_convergent_solve():
    plan = straight_walk_plan(2, 0.2, StepTiming(0.8, 0.3, 1.6, 1.0))
    com = PinocchioCenterOfMass(MODEL, LEG_NAMES)
    with pytest.raises(ValueError, match="leg geometry"):
        WalkingPattern(plan, com_model=com)

    # A tolerance under the rounding of the CoM itself cannot be met: the solve must say so.
    params = WalkingParams(com_tolerance_m=1e-20, com_max_iterations=3)
    with pytest.raises(LegIkError, match="did not converge in 3 iterations"):
        WalkingPattern(plan, params, legs=LegsGeometry.dyros_jet(), com_model=com)
