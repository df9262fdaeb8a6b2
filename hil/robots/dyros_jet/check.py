"""What a DYROS-JET configuration must satisfy beyond the schema: a URDF the controller's
model of the legs builds from (pinocchio, ~20 ms), found out before the emulator starts."""

from __future__ import annotations

from hil.config import Config, ConfigError, robot_description_text
from hil.robots.urdf_errors import parser_messages


def check_description(config: Config) -> None:
    text = robot_description_text(config)  # a URDF, or refused naming the file
    from controller.humanoid import LegModel  # pinocchio: only for a humanoid

    with parser_messages() as parser_said:  # the URDF parser writes its errors to fd 2 itself
        try:
            LegModel(text)
            failure = None
        except Exception as exc:  # noqa: BLE001 - pinocchio raises its own types: say them
            failure = exc
    if failure is not None:
        said = " ".join(line.strip() for line in parser_said() if line.startswith("Error:"))
        raise ConfigError(
            f"{config.source} [model] description: {config.model.description!r} is not a "
            f"description of DYROS-JET's legs: {type(failure).__name__}: {failure}"
            + (f" (the URDF parser: {said})" if said else "")
        ) from None
