"""What several commands share: the checked configuration, --attach, --inject."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

from hil.config import Config, ConfigError, load_config, robot_of
from hil.robots import robot_of_experiment
from hil.session import ConnectionOverrides
from hil.vocabulary import Robot
from hil.wiring import check_devices
from sim_backend.scenario import EMULATOR_FAULTS, FaultEvent, parse_fault

LOOP_FAULTS = ("overrun",)


def checked_config(
    path: Path | None, robot: str | None = None, experiment: str | None = None
) -> Config:
    """The configuration file (or the built-in one of `robot`, by default the experiment's),
    its device figures checked by the drivers, its robot the one the experiment is for."""
    if path is not None and robot is not None:
        raise ConfigError(
            f"--robot {robot} picks a built-in configuration; --config {path} names its own "
            "robot ([model] robot): give one of them"
        )
    wanted = robot_of_experiment(experiment) if experiment else None
    config = load_config(path, robot=robot or wanted or Robot.TESTBED)
    if wanted is not None and robot_of(config) is not wanted:
        raise ConfigError(
            f"experiment {experiment!r} is for the robot {str(wanted)!r}; {config.source} "
            f"describes {str(robot_of(config))!r} ([model] robot)"
            + (f": drop --robot or use --robot {wanted}" if path is None else "")
        )
    check_devices(config)
    return config


def connection_overrides(args: argparse.Namespace) -> ConnectionOverrides:
    return ConnectionOverrides(
        port=args.port,
        baudrate=args.baudrate,
        can_interface=args.can_interface,
        can_channel=args.can_channel,
    )


def load_attach(text: str) -> dict[str, Any]:
    """--attach: the JSON line `hil emulate` printed, or a file whose first line it is."""
    text = text.strip()
    if not text.startswith("{"):  # not the line itself: a file holding it
        path = Path(text).expanduser()
        if not path.is_file():
            raise ConfigError(
                f"--attach {text}: no such file (give the JSON line `hil emulate` printed, or "
                "a file holding it)"
            )
        try:
            lines = path.read_text().splitlines()
        except (OSError, UnicodeDecodeError) as exc:
            raise ConfigError(f"--attach {text}: cannot read it: {exc}") from None
        if not lines:
            raise ConfigError(f"--attach {text}: the file is empty")
        text = lines[0]
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ConfigError(f"--attach: not the JSON line `hil emulate` prints: {exc}") from None
    if not isinstance(data, dict):
        raise ConfigError("--attach: not the JSON object `hil emulate` prints")
    for key in ("dynamixel_port", "baudrate", "can"):
        if key not in data:
            raise ConfigError(f"--attach: the JSON line has no {key!r}")
    return data


def parse_injections(
    texts: list[str],
) -> tuple[tuple[FaultEvent, ...], tuple[tuple[float, float], ...]]:
    """--inject arguments -> (emulator faults, loop overruns as (start_s, duration_s))."""
    emulator: list[FaultEvent] = []
    overruns: list[tuple[float, float]] = []
    for text in texts:
        kind = text.partition("@")[0].strip()
        if kind in LOOP_FAULTS:
            _, _, when = text.partition("@")
            start, _, duration = when.partition("+")
            try:
                window = (float(start or 0.0), float(duration) if duration else 0.02)
            except ValueError:
                raise ConfigError(
                    f"bad --inject {text!r}: expected overrun@START[+DURATION]"
                ) from None
            if not all(math.isfinite(v) and v >= 0 for v in window) or window[1] <= 0:
                raise ConfigError(f"bad --inject {text!r}: times must be finite, start >= 0")
            overruns.append(window)
            continue
        if kind not in EMULATOR_FAULTS:
            raise ConfigError(
                f"bad --inject {text!r}: unknown fault {kind!r}; choose one of "
                f"{list(EMULATOR_FAULTS + LOOP_FAULTS)}"
            )
        try:
            emulator.append(parse_fault(text))
        except ValueError as exc:
            raise ConfigError(f"bad --inject: {exc}") from None
    return tuple(emulator), tuple(overruns)
