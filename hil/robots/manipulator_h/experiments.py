"""MANIPULATOR-H's experiments (hil/experiments/arm.py's kinds), at its zero pose: the upper
arm upright, the forearm level (joint2 and joint3 carry the arm's weight: 4.8 and 4.0 N m by
its URDF), the tool 0.41 m out and 0.45 m up.

    arm-hold        hold the zero pose against gravity
    arm-push        the same, pushed down at the tool: 20 N for 0.2 s (4 N s)
    arm-trajectory  a joint-space move of every joint to a reach and back (cosine, 2 s each)
    arm-contact     the elbow (joint3) lowers the tool onto a block below it and 0.1 rad past
                    (the testbed's contact: a 1 s hold, a 2 s cosine of 0.3 rad, contact at
                    0.2 rad, near 2.2 s); the block's force sensor is [force_sensor]
"""

from __future__ import annotations

from hil.experiments.arm import (
    HoldExperiment,
    JointMove,
    PushExperiment,
    TrajectoryExperiment,
)
from hil.experiments.arm_contact import ArmContactExperiment
from hil.experiments.base import Block, ToolPush, World

ZERO = (0.0,) * 6
REACH = (0.4, 0.4, -0.3, 0.3, 0.3, 0.3)  # every joint moves, within its +-1.5 rad

ARM_HOLD = HoldExperiment(
    name="arm-hold",
    title="MANIPULATOR-H holds its zero pose against gravity",
    duration_s=5.0,
    start_rad=ZERO,
)
ARM_PUSH = PushExperiment(
    name="arm-push",
    title="MANIPULATOR-H holding its zero pose, pushed down at the tool (20 N, 0.2 s)",
    duration_s=6.0,
    start_rad=ZERO,
    world=World(tool_pushes=(ToolPush(start_s=2.0, duration_s=0.2, force_n=(0.0, 0.0, -20.0)),)),
)
ARM_TRAJECTORY = TrajectoryExperiment(
    name="arm-trajectory",
    title="MANIPULATOR-H moves every joint to a reach and back (cosine, 2 s each way)",
    duration_s=6.0,
    start_rad=ZERO,
    moves=(JointMove(1.0, 2.0, ZERO, REACH), JointMove(3.0, 2.0, REACH, ZERO)),
)
# The elbow at 0.2 rad puts the tool point at (0.409, 0, 0.377) m (the URDF, computed by the
# emulator's plant); the tool's 20 mm sphere touches a block whose top is 0.357 m up.
PRESSED = (0.0, 0.0, 0.3, 0.0, 0.0, 0.0)
ARM_CONTACT = ArmContactExperiment(
    name="arm-contact",
    title="MANIPULATOR-H lowers its tool onto a block and 0.1 rad past it (the elbow)",
    duration_s=8.0,
    start_rad=ZERO,
    moves=(JointMove(1.0, 2.0, ZERO, PRESSED),),
    world=World(block=Block(centre_m=(0.41, 0.0, 0.3067), size_m=(0.2, 0.2, 0.1))),
    pressing_joint=2,
)
EXPERIMENTS = (ARM_HOLD, ARM_PUSH, ARM_TRAJECTORY, ARM_CONTACT)
