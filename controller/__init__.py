"""The math of Kim et al., ICRA 2018, for n flexible joints: pure numpy/scipy, no I/O.

One module per block of the paper: model (1)-(4), (20); LQR (21)-(24); DOB (9)-(11);
gravity compensator (5)-(8); composition (25); state estimation from the encoders; the four
controllers the loop runs (`ControllerKind`: "pid", "gc", "gc+lqr", "gc+lqr+dob"). Imports
nothing of ours; device facts (encoder resolutions, servo figures) come from the caller.
"""

from controller.composition import COMPOSITION_READINGS, Composition, CompositionReading
from controller.controllers import make_controller
from controller.dob import (
    LAB_DOB_CUTOFF_HZ,
    LAB_Q_FILTER_POLE,
    CubicRamp,
    DisturbanceObserver,
    q_filter_pole,
)
from controller.estimation import (
    LINK_VELOCITY_INCREMENTS,
    FlexibleJointStateEstimator,
    LinkVelocityIncrement,
)
from controller.gravity import (
    GC_COMPLIANCES,
    GcCompliance,
    GravityCompensator,
    GravityModel,
    NoGravity,
    PendulumGravity,
    joint_static_compliance,
    servo_static_stiffness,
    support_force_split,
)
from controller.joint_controller import ControllerUsageError, ControlTerms, JointController
from controller.lqr import (
    COUPLINGS,
    LQR_DESIGNS,
    Coupling,
    LqrDesign,
    LqrWeights,
    TrackingGain,
    design_continuous_tracking_lqr,
)
from controller.lqr_designs import (
    KDIST_REFERENCES,
    SERVO_MODELS,
    GainDesigner,
    KdistReference,
    ServoModel,
    design_discrete_tracking_lqr,
)
from controller.model import (
    FlexibleJointParams,
    discretise,
    flexible_joint_state_space,
    single_link_sm,
)
from controller.params import CONTROLLER_NAMES, LAB_KDIST_RAMP_S, ControllerKind, ControllerParams
from controller.planned_motion import GcLoad, PlannedMotion
from controller.servo_cascade import ServoCascadeParams

__all__ = [
    "COMPOSITION_READINGS",
    "COUPLINGS",
    "Coupling",
    "KDIST_REFERENCES",
    "KdistReference",
    "CONTROLLER_NAMES",
    "LAB_DOB_CUTOFF_HZ",
    "LAB_KDIST_RAMP_S",
    "LAB_Q_FILTER_POLE",
    "LINK_VELOCITY_INCREMENTS",
    "LQR_DESIGNS",
    "SERVO_MODELS",
    "Composition",
    "CompositionReading",
    "ControlTerms",
    "ControllerKind",
    "ControllerParams",
    "ControllerUsageError",
    "CubicRamp",
    "DisturbanceObserver",
    "FlexibleJointParams",
    "FlexibleJointStateEstimator",
    "GC_COMPLIANCES",
    "GcCompliance",
    "GainDesigner",
    "GcLoad",
    "GravityCompensator",
    "GravityModel",
    "JointController",
    "LinkVelocityIncrement",
    "LqrDesign",
    "LqrWeights",
    "NoGravity",
    "PendulumGravity",
    "PlannedMotion",
    "ServoCascadeParams",
    "ServoModel",
    "TrackingGain",
    "joint_static_compliance",
    "servo_static_stiffness",
    "design_continuous_tracking_lqr",
    "design_discrete_tracking_lqr",
    "discretise",
    "flexible_joint_state_space",
    "make_controller",
    "q_filter_pole",
    "single_link_sm",
    "support_force_split",
]
