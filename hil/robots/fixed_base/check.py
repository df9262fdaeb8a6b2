"""What a fixed-base robot's configuration must satisfy against its URDF, checked before
anything opens (ConfigError naming the key):

- `[model] description` is a URDF pinocchio builds, with every [[joint]] name one of its one-axis
  joints, `locked_joint_angles_rad` naming only its other joints, `tool_link` one of its links;
- `[model] sm_coupling` "diagonal" or "full" (a fixed base has no closed chain);
- every joint's actuator can hold the joint's static load: the largest |tau_g| the joint
  carries at any posture within the [[joint]] limits (the locked joints at their angles), found
  by a search (`worst_static_load`), within the actuator model's continuous torque (the e-Manual
  specification table) and within its configured current cap (`torque_limit_a` times the
  model's torque constant) where one is set. (Two joints on one ID in a chain: the schema's.)
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from controller import Coupling
from drivers.dynamixel import ACTUATOR_MODELS, model_number
from hil.config import Config, ConfigError, robot_description_text
from hil.robots.urdf_errors import parser_messages

if TYPE_CHECKING:
    from controller.fixed_base import FixedBaseModel

# the search's starts besides the limits' middle and 0: seeded, the same every time
SEARCH_STARTS = 12
SEARCH_SEED = 2018


def check_fixed_base(config: Config) -> None:
    model = _built(config)
    source, section = config.source, config.model
    if Coupling(section.sm_coupling) is Coupling.CLOSED_CHAIN:
        raise ConfigError(
            f"{source} [model] sm_coupling: 'closed-chain' is the humanoid's double support; a "
            "fixed-base robot's Sm is 'diagonal' or 'full'"
        )
    if section.tool_link is not None and not model.model.existFrame(section.tool_link):
        raise ConfigError(
            f"{source} [model] tool_link: {section.tool_link!r} is no link of "
            f"{section.description!r}"
        )
    low = np.array([j.min_angle_rad for j in config.joints])
    high = np.array([j.max_angle_rad for j in config.joints])
    for index, joint in enumerate(config.joints):
        load, posture = worst_static_load(model, index, low, high)
        name = config.actuator_of(joint)
        actuator = ACTUATOR_MODELS[model_number(name)]  # a known name: the drivers checked
        capacities = [("continuous torque", actuator.continuous_torque_nm)]
        if joint.torque_limit_a is not None:
            constant = actuator.continuous_torque_nm / actuator.continuous_current_a
            capacities.append(
                (f"torque_limit_a {joint.torque_limit_a:g} A", joint.torque_limit_a * constant)
            )
        for what, torque in capacities:
            if torque < load:
                angles = ", ".join(f"{a:.2f}" for a in posture)
                raise ConfigError(
                    f"{source} [[joint]] #{index + 1} {joint.name!r} actuator: {name}'s {what} "
                    f"({torque:.1f} N m) cannot hold the joint's static load, {load:.1f} N m at "
                    f"the worst posture within the [[joint]] limits (link angles {angles} rad)"
                )


def _built(config: Config) -> FixedBaseModel:
    text = robot_description_text(config)  # a URDF, or refused naming the file
    from controller.fixed_base import FixedBaseModel  # pinocchio: only for such a robot

    with parser_messages() as parser_said:  # the URDF parser writes its errors to fd 2 itself
        try:
            return FixedBaseModel(text, config.joint_names, config.model.locked_joint_angles_rad)
        except ValueError as exc:
            failure: Exception = exc
        except Exception as exc:  # noqa: BLE001 - pinocchio raises its own types: say them
            failure = exc
    said = " ".join(line.strip() for line in parser_said() if line.startswith("Error:"))
    key = _key_of(config, str(failure))
    raise ConfigError(
        f"{config.source} {key}: {config.model.description!r} does not describe this robot: "
        f"{failure}" + (f" (the URDF parser: {said})" if said else "")
    ) from None


def _key_of(config: Config, reason: str) -> str:
    """The key a model's refusal is about: a [[joint]] it does not have, a locked joint."""
    for number, joint in enumerate(config.joints, start=1):
        if repr(joint.name) in reason:
            return f"[[joint]] #{number} {joint.name!r} name"
    if "locked" in reason:
        return "[model] locked_joint_angles_rad"
    return "[model] description"


def worst_static_load(
    model: FixedBaseModel, joint: int, low: np.ndarray, high: np.ndarray
) -> tuple[float, np.ndarray]:
    """The largest |tau_g| joint `joint` carries at any link angles within [low, high] (every
    joint), and where: L-BFGS-B on -tau_g^2 / 2 with pinocchio's gravity derivatives, from the
    limits' middle, 0 (clipped) and SEARCH_STARTS seeded points."""
    import pinocchio as pin
    from scipy.optimize import minimize

    pmodel, data, v = model.model, model.model.createData(), model.v_index

    def cost(angles: np.ndarray) -> tuple[float, np.ndarray]:
        q = model.configuration(angles)
        torque = pin.computeGeneralizedGravity(pmodel, data, q)[v[joint]]
        slope = pin.computeGeneralizedGravityDerivatives(pmodel, data, q)[v[joint]][v]
        return -0.5 * torque * torque, -torque * slope

    rng = np.random.default_rng(SEARCH_SEED)
    starts = [0.5 * (low + high), np.clip(0.0, low, high)]
    starts += [rng.uniform(low, high) for _ in range(SEARCH_STARTS)]
    best, where = 0.0, starts[0]
    for start in starts:
        found = minimize(
            cost, start, jac=True, method="L-BFGS-B", bounds=list(zip(low, high, strict=True))
        )
        load = float(np.sqrt(max(-2.0 * found.fun, 0.0)))
        if load > best:
            best, where = load, found.x
    return best, where
