"""From the configuration's robot model and a controller choice to a running controller."""

from __future__ import annotations

import numpy as np

from controller import (
    ControllerParams,
    FlexibleJointParams,
    JointController,
    LqrWeights,
    PendulumGravity,
    make_controller,
)
from hil.config import Config, ConfigError
from hil.vocabulary import ControllerChoice


def joint_params(config: Config) -> FlexibleJointParams:
    """K, D, Kp per joint from [model] (with its per-joint overrides)."""
    model = config.model
    names = config.joint_names

    def figures(key: str) -> np.ndarray:
        return np.array([model.joint_figure(name, key) for name in names])

    return FlexibleJointParams(
        stiffness_nm_per_rad=figures("stiffness_nm_per_rad"),
        damping_nms_per_rad=figures("damping_nms_per_rad"),
        servo_gain_per_s=figures("servo_gain_per_s"),
    )


def build_controller(config: Config, choice: ControllerChoice, period_s: float) -> JointController:
    """The chosen controller for the configured robot (single links: Sm = 1/I, a pendulum's
    gravity with m r per joint)."""
    section = config.controller
    n = len(config.joints)
    reading = choice.reading or section.composition
    if reading == "accumulated-integral" and section.dob_integral_time_s is None:
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
            section.dob_integral_time_s if reading == "accumulated-integral" else None
        ),
        discretisation=section.discretization,  # type: ignore[arg-type]
        link_velocity_increment=section.link_velocity_increment,  # type: ignore[arg-type]
    )
    model = config.model
    sm = np.eye(n) / model.link_inertia_kg_m2
    # m*r is all the pendulum model needs: pass it as a mass at unit distance.
    gravity = PendulumGravity(np.full(n, model.gravity_moment_kg_m), np.ones(n))
    return make_controller(choice.kind, params, sm=sm, dt_s=period_s, gravity=gravity)
