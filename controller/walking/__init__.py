"""Walking pattern generator for the humanoid (Kim et al., ICRA 2018, Sec. IV-C): pure math.

Footstep plan -> timeline and ZMP reference -> CoM by Kajita's ZMP preview control on the
cart-table -> quintic swing feet -> closed-form leg IK -> `WalkingPattern`, read per tick; plus
the Kdist schedule by phase, and the lab's walking scheme around the pattern (`lab_terms`: the
CoM feedback on the pelvis, the position-mode deflection model and support hip-roll
offsets), and our CoM stabiliser (`com_stabiliser`). Imports nothing of ours outside
`controller`.
"""

from controller.walking.center_of_mass import CenterOfMassModel, PinocchioCenterOfMass
from controller.walking.com_stabiliser import CenterOfMassStabiliser, StabiliserState
from controller.walking.footsteps import (
    Footstep,
    FootstepPlan,
    FootstepPlanError,
    Side,
    StepTiming,
    straight_walk_plan,
)
from controller.walking.kdist_schedule import KdistSchedule, kdist_gain, kdist_per_joint
from controller.walking.lab_terms import (
    LAB_COM_FEEDBACK_GAIN,
    CenterOfMassFeedback,
    CenterOfMassMeasurement,
    DeflectionModel,
    SupportHipRollOffsets,
)
from controller.walking.leg_ik import (
    LegGeometry,
    LegIkError,
    LegsGeometry,
    leg_inverse_kinematics,
    legs_inverse_kinematics,
)
from controller.walking.pattern import WalkingParams, WalkingPattern, WalkingSample, yaw_rotation
from controller.walking.preview_control import (
    CartTableParams,
    CartTableTrajectory,
    PreviewGains,
    PreviewWeights,
    design_preview_controller,
    track_zmp_reference,
)
from controller.walking.swing_foot import SwingFootTrajectory, quintic_blend
from controller.walking.timeline import PhaseSample, SegmentKind, Support, WalkTimeline
from controller.walking.zmp_reference import ZmpReferenceParams, ZmpTransition, zmp_reference

__all__ = [
    "LAB_COM_FEEDBACK_GAIN",
    "CenterOfMassFeedback",
    "CenterOfMassMeasurement",
    "DeflectionModel",
    "StabiliserState",
    "SupportHipRollOffsets",
    "CartTableParams",
    "CartTableTrajectory",
    "CenterOfMassModel",
    "CenterOfMassStabiliser",
    "Footstep",
    "FootstepPlan",
    "FootstepPlanError",
    "KdistSchedule",
    "LegGeometry",
    "LegIkError",
    "LegsGeometry",
    "PhaseSample",
    "PinocchioCenterOfMass",
    "PreviewGains",
    "PreviewWeights",
    "SegmentKind",
    "Side",
    "StepTiming",
    "Support",
    "SwingFootTrajectory",
    "WalkTimeline",
    "WalkingParams",
    "WalkingPattern",
    "WalkingSample",
    "ZmpReferenceParams",
    "ZmpTransition",
    "design_preview_controller",
    "kdist_gain",
    "kdist_per_joint",
    "leg_inverse_kinematics",
    "legs_inverse_kinematics",
    "quintic_blend",
    "straight_walk_plan",
    "track_zmp_reference",
    "yaw_rotation",
    "zmp_reference",
]
