"""`hil monitor`: a live table of every joint, read-only (see hil/bringup/monitor.py)."""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TextIO

from drivers.joint_bus import ActuatorFault, BusError, JointBus
from hil.bringup import JointStatus, MonitorSample, monitor
from hil.cli.common import checked_config, connection_overrides, load_attach
from hil.cli.exit_codes import ExitCode
from hil.config import Config, ConfigError
from hil.loop import StopFlag
from hil.output.strict_json import dumps
from hil.wiring import Connection, make_bus

# --rate: from a sample every 10 s to the loop's 200 Hz (a slower rate is no live table, and
# 1/rate overflowed a sleep at 1e-300)
MIN_RATE_HZ = 0.1
MAX_RATE_HZ = 200.0

_COLUMNS = (
    ("joint", 10),
    ("actuator", 17),
    ("motor rad", 10),
    ("link rad", 10),
    ("defl mrad", 9),
    ("vel rad/s", 9),
    ("cur A", 7),
    ("temp C", 6),
    ("input V", 7),
    ("torque", 6),
    ("fault", 12),
    ("link age ms", 11),
)


def _number(value: float, digits: int) -> str:
    return "-" if not math.isfinite(value) else f"{value:+.{digits}f}"


def _row(joint: JointStatus) -> str:
    fault = ActuatorFault.describe(joint.actuator_fault) if joint.actuator_fault else "-"
    age_ms = joint.link_age_s * 1e3
    cells = (
        joint.name,
        joint.actuator,
        _number(joint.motor_angle_rad, 5),
        _number(joint.link_angle_rad, 5),
        _number(joint.deflection_rad * 1e3, 2),
        _number(joint.motor_velocity_rad_s, 3),
        _number(joint.motor_current_a, 2),
        _number(joint.temperature_c, 0).lstrip("+"),
        _number(joint.input_voltage_v, 1).lstrip("+"),
        "ON" if joint.torque_enabled else "off",
        fault,
        f"{age_ms:.1f}" if math.isfinite(age_ms) else "never",
    )
    text = "  ".join(f"{cell:>{width}}" for cell, (_, width) in zip(cells, _COLUMNS, strict=True))
    flags = ", ".join(str(flag).upper() for flag in joint.flags)
    return text + (f"  !! {flags}" if flags else "")


def table_text(sample: MonitorSample) -> str:
    header = "  ".join(f"{name:>{width}}" for name, width in _COLUMNS)
    lines = [f"t = {sample.time_s:7.2f} s", header, *(_row(j) for j in sample.joints)]
    return "\n".join(lines)


def _printer(args: argparse.Namespace, out: TextIO) -> Callable[[MonitorSample], None]:
    if args.json:

        def print_json(sample: MonitorSample) -> None:
            print(dumps(sample.record()), file=out, flush=True)

        return print_json
    live = out.isatty()
    drawn = [0]

    def print_table(sample: MonitorSample) -> None:
        text = table_text(sample)
        if live and drawn[0]:
            out.write(f"\x1b[{drawn[0]}F\x1b[J")  # back to the table's first line, clear below
        out.write(text + "\n" + ("" if live else "\n"))
        out.flush()
        drawn[0] = text.count("\n") + 1

    return print_table


def connection_of(args: argparse.Namespace, config: Config) -> Connection:
    """--attach JSON (an emulator) or the configuration's ports, with any overrides."""
    connection = (
        Connection.from_endpoints(load_attach(args.attach), config)
        if args.attach
        else Connection.from_config(config)
    )
    return connection.with_overrides(**connection_overrides(args).given)


@contextmanager
def read_only_bus(args: argparse.Namespace, config: Config) -> Iterator[JointBus]:
    """The robot's bus opened read-only (nothing is written to any actuator); closed after."""
    bus = make_bus(config, connection_of(args, config), read_only=True)
    bus.open()
    try:
        yield bus
    finally:
        bus.close()


def cmd_monitor(args: argparse.Namespace) -> int:
    if not (math.isfinite(args.rate) and MIN_RATE_HZ <= args.rate <= MAX_RATE_HZ):
        raise ConfigError(
            f"--rate: must be in [{MIN_RATE_HZ:g}, {MAX_RATE_HZ:g}] Hz, got {args.rate}"
        )
    if args.duration is not None and not (math.isfinite(args.duration) and args.duration > 0):
        raise ConfigError(f"--duration: must be a finite time > 0 s, got {args.duration}")
    config = checked_config(args.config)

    def note(text: str) -> None:
        print(f"hil monitor: {text}", file=sys.stderr, flush=True)

    stop = StopFlag()
    stop.install()
    try:
        with read_only_bus(args, config) as bus:
            note(
                f"reading {', '.join(config.joint_names)} at {args.rate:g} Hz, read-only "
                "(nothing is written to the actuators); Ctrl-C to stop"
            )
            count = monitor(
                config,
                bus,
                rate_hz=args.rate,
                duration_s=args.duration,
                on_sample=_printer(args, sys.stdout),
                on_note=note,
                stopped=lambda: stop.reason is not None,
            )
    except BusError as exc:
        print(f"hil monitor: {exc}", file=sys.stderr)
        return ExitCode.FAILED
    finally:
        stop.restore()
    note(f"{count} samples; the devices were left as found")
    return ExitCode.OK
