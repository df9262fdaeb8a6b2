"""Everything a configuration's devices must satisfy, checked before anything is opened."""

from __future__ import annotations

import contextlib
import math
import os
import sys
import tempfile
from collections.abc import Callable, Iterator

from hil.config import Config, ConfigError, robot_description_text
from hil.wiring.connection import Connection
from hil.wiring.emulation import plant_servo_noise
from hil.wiring.hardware import bus_config, encoder_counts_per_rev

# A CiA 406 position value is an INTEGER32 count (0x6004): no reading lies outside +-2**31.
INT32_COUNTS = 2**31


def check_devices(config: Config) -> None:
    """Every device figure the drivers check, the link encoders' offsets, the robot description
    and the [emulator] section, checked now (no port is opened), whatever the run will drive:
    ConfigError naming the file and the device or key."""
    try:
        bus_config(config, Connection.from_config(config, require_ports=False))
    except ValueError as exc:
        raise ConfigError(f"{config.source}: {exc}") from exc
    _check_encoder_offsets(config)
    _check_robot_description(config)
    plant_servo_noise(config)


def _check_encoder_offsets(config: Config) -> None:
    """An encoder offset is a reading of the encoder (at the link's zero): one its INTEGER32
    count cannot hold would refuse every run at its start gate, after the bus was opened."""
    for number, joint in enumerate(config.joints, start=1):
        per_rev = encoder_counts_per_rev(joint)
        reach_rad = 2.0 * math.pi * INT32_COUNTS / per_rev
        if abs(joint.encoder_offset_rad) > reach_rad:
            raise ConfigError(
                f"{config.source} [[joint]] #{number} {joint.name!r} encoder_offset_rad: "
                f"{joint.encoder_offset_rad!r} rad is no reading of its encoder (an INTEGER32 "
                f"count at {per_rev} counts/rev reaches +-{reach_rad:.0f} rad)"
            )


def _check_robot_description(config: Config) -> None:
    """A humanoid's [model] description must be a URDF the controller's model can be built
    from, with its leg joints (pinocchio, ~20 ms): not found out after the emulator started."""
    if config.model.robot != "dyros-jet":
        return
    text = robot_description_text(config)  # a URDF, or refused naming the file
    from controller.humanoid import LegModel  # pinocchio: only for a humanoid

    with _stderr_kept() as parser_said:  # the URDF parser writes its errors to fd 2 itself
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


@contextlib.contextmanager
def _stderr_kept() -> Iterator[Callable[[], list[str]]]:
    """File descriptor 2 goes to a temporary file for the block; yields what was written."""
    lines: list[str] = []
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile(mode="w+") as kept:
        os.dup2(kept.fileno(), 2)
        try:
            yield lambda: lines
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            kept.seek(0)
            lines += kept.read().splitlines()
