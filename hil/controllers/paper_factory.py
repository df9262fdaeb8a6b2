"""From the configuration's robot model and a controller choice to a running controller."""

from __future__ import annotations

import numpy as np

from controller import (
    CompositionReading,
    ControllerParams,
    FlexibleJointParams,
    GcCompliance,
    JointController,
    LqrWeights,
    ServoCascadeParams,
    ServoModel,
    joint_static_compliance,
    make_controller,
)
from hil.config import Config, ConfigError
from hil.controllers.robot_model import RobotModel, robot_model
from hil.vocabulary import ControllerChoice


def model_figures(config: Config, key: str) -> np.ndarray:
    """One [model] figure per joint (with its per-joint overrides), in the joints' order."""
    return np.array([config.model.joint_figure(name, key) for name in config.joint_names])


def joint_params(config: Config) -> FlexibleJointParams:
    """K, D, Kp per joint from [model] (with its per-joint overrides)."""
    return FlexibleJointParams(
        stiffness_nm_per_rad=model_figures(config, "stiffness_nm_per_rad"),
        damping_nms_per_rad=model_figures(config, "damping_nms_per_rad"),
        servo_gain_per_s=model_figures(config, "servo_gain_per_s"),
    )


def gc_compliance(config: Config, reading: GcCompliance | None = None) -> np.ndarray:
    """C of the gravity compensator (8) per joint [rad/N m] in `reading` (default: the
    configuration's `[controller] gc_compliance`): "joint" 1/K + 1/(Kpp kv) from [model],
    "gear" the paper's 1/K."""
    reading = GcCompliance(reading or config.controller.gc_compliance)
    stiffness = model_figures(config, "stiffness_nm_per_rad")
    if reading is GcCompliance.GEAR:
        return 1.0 / stiffness
    return joint_static_compliance(
        stiffness,
        model_figures(config, "position_gain_per_s"),
        model_figures(config, "velocity_gain_nms_per_rad"),
    )


def servo_cascade(config: Config) -> ServoCascadeParams | None:
    """The LQR's servo model from [model]: None for the paper's first-order (4), else the
    cascade's figures per joint."""
    if config.model.servo_model is not ServoModel.CASCADE:
        return None
    return ServoCascadeParams(
        velocity_gain_nms_per_rad=model_figures(config, "velocity_gain_nms_per_rad"),
        rotor_inertia_kg_m2=model_figures(config, "rotor_inertia_kg_m2"),
        viscous_friction_nms_per_rad=model_figures(config, "motor_viscous_friction_nms_per_rad"),
    )


def build_controller(
    config: Config,
    choice: ControllerChoice,
    period_s: float,
    robot: RobotModel | None = None,
    start_rad: np.ndarray | None = None,
    contact: object = None,
) -> JointController:
    """The chosen controller for the configured robot (hil/controllers/robot_model.py), its LQR
    designed on the Sm of the start posture `start_rad` (the experiment's first reference) and
    the LQR's contact there (`RobotModel.lqr_contacts`)."""
    section = config.controller
    n = len(config.joints)
    robot = robot or robot_model(config)
    start = np.zeros(n) if start_rad is None else np.asarray(start_rad, dtype=float)
    reading = choice.reading or section.composition
    if reading == CompositionReading.ACCUMULATED_INTEGRAL and section.dob_integral_time_s is None:
        raise ConfigError(
            f"{config.source} [controller] dob_integral_time_s: the reading "
            "'accumulated-integral' needs it (the servo's velocity-loop integral time)"
        )
    params = ControllerParams(
        joints=joint_params(config),
        lqr_weights=LqrWeights(
            tracking_error_weight=section.q_error,
            state_increment_weight=section.q_state,
            input_increment_weight=section.r_input,
        ),
        kdist=choice.kdist,
        kdist_ramp_s=section.kdist_ramp_s,
        dob_cutoff_hz=section.dob_cutoff_hz,
        dob_filter_pole=section.dob_filter_pole,
        composition=reading,  # type: ignore[arg-type]
        dob_integral_time_s=(
            section.dob_integral_time_s
            if reading == CompositionReading.ACCUMULATED_INTEGRAL
            else None
        ),
        discretisation=section.discretization,  # type: ignore[arg-type]
        link_velocity_increment=section.link_velocity_increment,  # type: ignore[arg-type]
        lqr_coupling=robot.lqr_coupling,  # type: ignore[arg-type]
        gc_compliance_rad_per_nm=gc_compliance(config, choice.gc_compliance),
        servo_cascade=servo_cascade(config),
        kdist_reference=section.kdist_reference,
        reference_feedforward=section.reference_feedforward,
        servo_feedforward=section.servo_feedforward,
        dob_expects_gravity_lag=section.dob_expects_gravity_lag,
    )
    sm = robot.sm(start, contact)
    return make_controller(choice.kind, params, sm=sm, dt_s=period_s, gravity=robot.gravity)
