"""The controller's design judged before anything starts: every run's LQR (Riccati) and DOB are
built from the configuration, as the loop will build them, before an emulator starts or a bus
opens. A design that does not exist (no stabilising Riccati solution, a singular matrix, gains
that are not finite) is a configuration error naming the keys it comes from (exit 2), not an
exception after the emulator started (exit 1, `LinAlgError: Singular matrix`, no key named).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Iterable

import numpy as np

from hil.config import Config, ConfigError
from hil.controllers.robot_model import RobotModel
from hil.experiments import Experiment
from hil.loop import build_controller, robot_model
from hil.robots import profile_of
from hil.vocabulary import ControllerChoice

# What a design is made of, by controller part (named in the error).
_LQR_KEYS = (
    "[model] stiffness_nm_per_rad, damping_nms_per_rad, servo_gain_per_s (and the cascade's "
    "figures with servo_model = 'cascade'), link_inertia_kg_m2 or the robot's description; "
    "[controller] q_error, q_state, r_input, discretization; [loop] rate_hz"
)
_DOB_KEYS = (
    "[controller] dob_cutoff_hz / dob_filter_pole, dob_integral_time_s, kdist; [model] "
    "servo_gain_per_s; [loop] rate_hz"
)


def comparison_runs(config: Config, named: str | None) -> list[tuple[Experiment, ControllerChoice]]:
    """The runs `hil run` without an experiment makes (the robot's comparison's plan)."""
    return profile_of(config).comparison(named).plan(config, True)


def check_designs(
    config: Config,
    runs: Iterable[tuple[Experiment, ControllerChoice]],
    duration_s: float | None = None,
) -> None:
    """Build each run's controller (LQR and DOB) as the loop will at its first tick; a design
    that does not exist is a ConfigError naming its keys. Controllers without either (pid, gc)
    have nothing to design."""
    robot: RobotModel | None = None
    seen: set[tuple[str, ControllerChoice]] = set()
    for experiment, choice in runs:
        kind = choice.kind  # a plug-in (None) is tried on a copy instead: hil/controllers/preflight
        if kind is None or not (kind.has_lqr or kind.has_dob) or (experiment.name, choice) in seen:
            continue
        seen.add((experiment.name, choice))
        robot = robot or robot_model(config)
        _check_design(config, robot, experiment, choice, duration_s or experiment.duration_s)


def _check_design(
    config: Config,
    robot: RobotModel,
    experiment: Experiment,
    choice: ControllerChoice,
    duration_s: float,
) -> None:
    period = config.loop.period_s
    n = len(config.joints)
    start = np.broadcast_to(experiment.reference(0.0), (n,))
    keys = _LQR_KEYS if choice.kind is not None and choice.kind.has_lqr else _DOB_KEYS
    where = f"{config.source}: the {choice.label} controller of {experiment.name}"
    try:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore", RuntimeWarning)
            contact = _first_contact(robot, experiment, period, duration_s)
            controller = build_controller(config, choice, period, robot, start, contact)
    except ConfigError:
        raise
    except (ValueError, ArithmeticError) as exc:  # LinAlgError is a ValueError
        raise ConfigError(
            f"{where} has no design with these figures ({type(exc).__name__}: {exc}); it is made "
            f"of {keys}"
        ) from None
    gain = getattr(controller, "lqr_gain", None)
    if gain is None:
        return
    parts = [gain.error_gain, gain.state_increment_gain]
    if gain.motor_velocity_increment_gain is not None:
        parts.append(gain.motor_velocity_increment_gain)
    radius = gain.spectral_radius
    if not all(np.isfinite(part).all() for part in parts) or (
        math.isfinite(radius) and radius >= 1.0
    ):
        raise ConfigError(
            f"{where} has no stabilising LQR design with these figures (gains finite: "
            f"{all(np.isfinite(p).all() for p in parts)}, the designed loop's spectral radius "
            f"{radius:.6g}); it is made of {_LQR_KEYS}"
        )


def _first_contact(
    robot: RobotModel, experiment: Experiment, period_s: float, duration_s: float
) -> object:
    """The LQR's contact at the first tick, as the loop computes it (hil.loop's
    ExperimentFeed: the paper's switch at mid double support needs the whole phase ahead)."""
    if not robot.rescheduled:
        return robot.lqr_contacts([experiment.support(0.0)])[0]
    ticks = max(1, math.ceil(duration_s / period_s - 1e-9))
    return robot.lqr_contacts([experiment.support(i * period_s) for i in range(ticks)])[0]
