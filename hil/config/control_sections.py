"""The configuration's controller side: the robot model the controller uses (`[model]`), the
controller (`[controller]`) and the walking scheme around the walks' pattern (`[walking]`).
Declared like the rest of the file (schema.py: strict types, finite numbers within their physical
ranges (hil.config.figures), no unknown keys)."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import Field, model_validator

from controller import (
    LAB_KDIST_RAMP_S,
    CompositionReading,
    Coupling,
    GcCompliance,
    GcLoad,
    KdistReference,
    LinkVelocityIncrement,
    LqrDesign,
    ServoModel,
)
from controller.walking import CenterOfMassMeasurement
from hil.config.figures import (
    Angle,
    Damping,
    GravityMoment,
    IntegralTime,
    Kdist,
    LinkInertia,
    LqrWeight,
    LqrWeightOrZero,
    RotorInertia,
    ServoGain,
    Stiffness,
    VelocityGain,
    ViscousFriction,
)
from hil.config.section import Section
from hil.vocabulary import ControllerKind, Robot

ToolPoint = Annotated[float, Field(ge=-2.0, le=2.0)]


class JointModelSection(Section):
    """Per-joint overrides of the model's gear and servo figures (`[model.joint.NAME]`; the
    first table of a `hil identify` fragment)."""

    stiffness_nm_per_rad: Stiffness | None = None
    damping_nms_per_rad: Damping | None = None
    servo_gain_per_s: ServoGain | None = None
    position_gain_per_s: ServoGain | None = None
    velocity_gain_nms_per_rad: VelocityGain | None = None
    velocity_integral_time_s: IntegralTime | None = None
    rotor_inertia_kg_m2: RotorInertia | None = None
    motor_viscous_friction_nms_per_rad: ViscousFriction | None = None


class ModelSection(Section):
    """The controller's (nominal) model of the robot: Kim et al. Sec. IV-A.

    `robot`, one of hil.vocabulary.Robot (its folder hil/robots/<name>/ says what its model is):
    "testbed" (the old name "single_link" reads as it): every joint drives its own link
    swinging in a vertical plane (the 1-DoF testbed): Sm = 1 / link_inertia_kg_m2, gravity
    torque m g r cos(angle).
    "dyros-jet": the humanoid's 12 leg joints, the whole robot from `description` (a URDF:
    a path, or the name of one shipped in hil/data/robots/): the gravity compensator (5)-(8)
    and the contact-projected Sm of (19), the LQR rescheduled every `gain_reschedule_period_s`
    off the 200 Hz path; `sm_coupling` "diagonal" (the lab's: one design per joint on Sm's
    diagonal), "full" (one design on the whole Sm; none exists in double support, where Sm is
    singular) or "closed-chain" (the whole Sm, designed on the motions the legs and the ground
    allow: controller/closed_chain.py; docs/studies/lqr_standing/ says why).
    `sm_contact`: which soles Sm holds on the ground: "both-feet" (both in double support) or
    "support-foot" (Kim et al. Sec. III-C: one foot, the other from the middle of each double
    support; `sm_standing_foot` when a run never leaves double support);
    controller/humanoid/support.py. It is not the gravity compensator's weight split.
    `servo_model`: the LQR's model of the actuator: "first-order" (the paper's (4) with
    servo_gain_per_s) or "cascade" (the position gain servo_gain_per_s, the velocity loop
    velocity_gain_nms_per_rad on the rotor's reflected inertia rotor_inertia_kg_m2, with
    motor_viscous_friction_nms_per_rad: controller/servo_cascade.py; needs [controller]
    discretization "zoh" or "continuous-cost").
    "fixed-base" (your own robot; hil/robots/fixed_base/) and "manipulator-h": a fixed-base
    robot of flexible joints from `description` (its URDF): tau_g of (5)-(8) is the joints'
    generalised gravity and Sm of (19) is M(theta)^-1 (pinocchio, every [[joint]] one of the
    URDF's joints, in any order; the URDF's other movable joints welded at
    `locked_joint_angles_rad`, 0 where not named), both posture-dependent (the LQR
    rescheduled as the humanoid's; `sm_coupling` "diagonal" or "full"). `tool_link` and
    `tool_point_m` (in that link's frame) name the tool the experiments push at and touch the
    block with.
    Gear and servo figures apply to every joint unless `[model.joint.NAME]` overrides them.

    The position servo's cascade, as `hil identify` fits it (same keys and units, so that its
    fragment pastes here): `position_gain_per_s` Kpp (None: `servo_gain_per_s`, the paper's
    first-order Kp of (4), which a cascade with a fast velocity loop is), the velocity loop's
    `velocity_gain_nms_per_rad` kv and `velocity_integral_time_s` Ti. The defaults are the
    H54-200-S500-R's at its default registers as the emulator models them
    (sim_backend/servo.py: kv = 2 pi 50 Hz x 0.25 kg m^2, Ti from the stock I/P gain ratio):
    its static stiffness Kpp kv = 785 N m/rad is what the gravity compensator's "joint"
    compliance adds to the gear's (`[controller] gc_compliance`; `hil model` prints both).

    Each figure's range, and why it ends where it does, is in hil/config/figures.py.
    """

    robot: Robot = Field(Robot.TESTBED, strict=False)
    description: str | None = None
    sm_coupling: Coupling = Field(Coupling.DIAGONAL, strict=False)
    # the lab's background thread: 100 ms; from a tick at 200 Hz to 1 s (a step's time: a gain
    # held longer was designed for another posture)
    gain_reschedule_period_s: float = Field(0.1, ge=0.005, le=1.0)
    sm_contact: Literal["both-feet", "support-foot"] = "both-feet"
    sm_standing_foot: Literal["left", "right"] = "left"
    servo_model: ServoModel = Field(ServoModel.FIRST_ORDER, strict=False)
    stiffness_nm_per_rad: Stiffness = 2000.0
    damping_nms_per_rad: Damping = 100.0
    servo_gain_per_s: ServoGain = 10.0
    position_gain_per_s: ServoGain | None = None  # None: servo_gain_per_s
    velocity_gain_nms_per_rad: VelocityGain = 78.5
    velocity_integral_time_s: IntegralTime = 15.0
    rotor_inertia_kg_m2: RotorInertia = 0.25  # the H54's rotor, reflected to the output
    motor_viscous_friction_nms_per_rad: ViscousFriction = 1.14  # its gearbox, viscous part
    link_inertia_kg_m2: LinkInertia = 0.376
    gravity_moment_kg_m: GravityMoment = 0.63
    locked_joint_angles_rad: dict[str, Angle] = Field(default_factory=dict)
    tool_link: str | None = Field(None, min_length=1)
    # a point of the tool link: within 2 m of its frame (farther is no tool an arm carries)
    tool_point_m: tuple[ToolPoint, ToolPoint, ToolPoint] = Field((0.0, 0.0, 0.0), strict=False)
    joint: dict[str, JointModelSection] = Field(default_factory=dict)

    def joint_figure(self, joint: str, key: str) -> float:
        override = self.joint.get(joint)
        value = getattr(override, key) if override is not None else None
        if value is None and key == "position_gain_per_s" and self.position_gain_per_s is None:
            return self.joint_figure(joint, "servo_gain_per_s")
        return float(value if value is not None else getattr(self, key))


class ControllerSection(Section):
    """The controller (Kim et al. Sec. III) and its options; controller/params.py
    ControllerParams says what each does. The choices are the controller package's own.

    gc_compliance: what the gravity compensator (8) offsets, ug = C tau_g: "joint" (default),
    C = 1/K + 1/(Kpp kv) from [model], the gear in series with the position servo's static
    stiffness, which is what the joint deflects under a load on the time scale of a step;
    "gear", the paper's literal K^-1, exact only for a servo that holds any load without lag
    (its model (4)). controller/gravity.py derives it; docs/humanoid.md compares the two.
    gc_load: what (5)-(7) hold where the experiment plans a motion (the walks): "weight" (the
    paper's: the static weight, split at the CoM) or "planned-motion" (ours, beyond the 2018
    paper: the ground reaction the plan needs, m (g - a_com), split at the plan's ZMP;
    controller/planned_motion.py, controller/humanoid/gravity.py). Without a plan (standing,
    the testbed) both are the paper's.
    dob_expects_gravity_lag: the DOB's nominal servo holds (8)'s load with the servo cascade's
    static stiffness Kpp kv (ours; [model] servo_model = "cascade" only): the paper's nominal
    (4) has no static lag, so on a servo with one the DOB reads the compensated weight's lag
    as a disturbance and yields to it (controller/controllers.py, docs/walking.md).
    The figures' ranges: hil/config/figures.py (the gain, the LQR's weights) and beside each key.
    """

    # A registry name (the paper's "pid", "gc", "gc+lqr", "gc+lqr+dob", or an installed
    # package's) or a plug-in, "path/to/file.py:Class" or "package.module:Class"
    # (hil/controllers/registry.py); `params` is the plug-in's own table, [controller.params],
    # validated by its Params when the controller is resolved.
    name: str = Field(str(ControllerKind.GC_LQR_DOB), min_length=1)
    params: dict[str, Any] = Field(default_factory=dict)
    gc_compliance: GcCompliance = Field(GcCompliance.JOINT, strict=False)
    gc_load: GcLoad = Field(GcLoad.WEIGHT, strict=False)
    kdist: Kdist = 1.0
    # a Kdist change ramps this long: at most 10 s, longer than any experiment's contact phase
    kdist_ramp_s: float = Field(LAB_KDIST_RAMP_S, ge=0, le=10.0)
    q_error: LqrWeight = 10.0  # Kim et al.: Q = 10 I, R = I
    q_state: LqrWeightOrZero = 1.0
    r_input: LqrWeight = 1.0
    # The Q filter by its cut-off (0.1 Hz up to the Nyquist frequency, checked with [loop]
    # rate_hz: a slower filter takes seconds to estimate anything, a 1.6 s time constant), or
    # by its pole (at most 0.997, a 0.1 Hz cut-off at 200 Hz); neither: 0.7.
    dob_cutoff_hz: float | None = Field(None, ge=0.1)
    dob_filter_pole: float | None = Field(None, ge=0, le=0.997)
    composition: CompositionReading = Field(CompositionReading.ACCUMULATED, strict=False)
    dob_integral_time_s: IntegralTime | None = None  # "accumulated-integral" needs it
    discretization: LqrDesign = Field(LqrDesign.EULER, strict=False)  # the LQR design
    kdist_reference: KdistReference = Field(KdistReference.PER_TICK, strict=False)
    reference_feedforward: bool = False  # the LQR's uc moves with the reference's increments
    servo_feedforward: bool = False  # with a plan: the goal leads by the servo's lag, v / Kp
    dob_expects_gravity_lag: bool = False  # the DOB's nominal servo lags under ug's load
    link_velocity_increment: LinkVelocityIncrement = Field(
        LinkVelocityIncrement.BACKWARD_DIFFERENCE, strict=False
    )

    @model_validator(mode="after")
    def _filter_and_reading(self) -> ControllerSection:
        if self.dob_cutoff_hz is not None and self.dob_filter_pole is not None:
            raise ValueError("give dob_cutoff_hz or dob_filter_pole, not both")
        reading = CompositionReading.ACCUMULATED_INTEGRAL
        if self.composition is reading and self.dob_integral_time_s is None:
            raise ValueError(
                "composition 'accumulated-integral' needs dob_integral_time_s (the servo's "
                "velocity-loop integral time; `hil identify` measures it)"
            )
        return self


class WalkingSection(Section):
    """The lab's walking scheme around the walking pattern (DYROS-JET's walks; the lab's
    psh117/dyros_jet walking_controller.cpp; controller/walking/lab_terms.py derives each term).

    com_feedback_gain: kp of the CoM feedback on the pelvis, per tick: the pelvis moves by kp
        (CoM desired - CoM measured from the link encoders) every tick, for every controller
        (it is the pattern's feedback); 0.15 is the lab's master, 0 turns it off (the plan's
        IK alone). com_feedback_limit_m bounds the pelvis correction. com_measured_from:
        "commanded-pelvis" (the lab's: the measured legs' CoM around the pelvis where the
        scheme puts it) or "stance-sole" (the whole CoM from the encoders, the stance sole flat).
    deflection_model, support_hip_roll_offsets: the lab's position-mode terms, applied to the
        default controller only (`pid`: the actuator's own position control; the lab applied
        them with its LQR off): the Humanoids-2016 deflection model a tau + b on hip pitch,
        knee and ankle pitch, and the support hip roll's ramped offsets (4 / 8.5 deg).
    com_measured_from "measured-pelvis": the lab's May-June 2018 form (pelvis measured + kp
        (CoM desired - CoM measured), kp 0.9-1.0, both measured with the stance sole flat).
    com_feedback_angles: the joint angles the CoM feedback (and the stabiliser) measure the
        robot by: "link" (the link encoders) or "motor" (the actuators' own angles, as the lab's
        code did: walking_controller.cpp `getRobotState` reads its model updated from them).
    com_stabiliser_gain, com_stabiliser_damping_s: ours, beyond the paper
        (controller/walking/com_stabiliser.py): every controller's commanded pelvis moves by
        -(gain e + damping e') with e the whole CoM's error measured from the link encoders
        (the stance sole flat); gain 0 and damping 0 turn it off.
    """

    com_feedback_gain: float = Field(0.15, ge=0, le=1)
    com_feedback_limit_m: float = Field(0.05, gt=0, le=0.2)
    com_measured_from: CenterOfMassMeasurement = Field(
        CenterOfMassMeasurement.COMMANDED_PELVIS, strict=False
    )
    com_feedback_angles: Literal["link", "motor"] = "link"
    deflection_model: bool = True
    support_hip_roll_offsets: bool = True
    com_stabiliser_gain: float = Field(0.0, ge=0, le=10)
    com_stabiliser_damping_s: float = Field(0.0, ge=0, le=1)
