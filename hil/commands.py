"""The `hil` sub-commands (argument handling and output; the work lives in the modules)."""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

from hil.config import ConfigError, load_config
from hil.emulation import emulator_spec, spec_from_json
from hil.experiments import get_experiment
from sim_backend.scenario import EMULATOR_FAULTS, FaultEvent, parse_fault

EXIT_OK, EXIT_FAILED, EXIT_USAGE = 0, 1, 2
LOOP_FAULTS = ("overrun",)


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
                overruns.append((float(start or 0.0), float(duration) if duration else 0.02))
            except ValueError:
                raise ConfigError(
                    f"bad --inject {text!r}: expected overrun@START[+DURATION]"
                ) from None
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


def cmd_emulate(args: argparse.Namespace) -> int:
    from sim_backend.server import serve

    if args.spec_file is not None:
        spec = spec_from_json(Path(args.spec_file).read_text())
    else:
        config = load_config(args.config)
        experiment = get_experiment(args.experiment) if args.experiment else None
        faults, overruns = parse_injections(args.inject)
        if overruns:
            raise ConfigError("overrun is a fault of the loop: inject it with `hil run --inject`")
        spec = emulator_spec(
            config,
            experiment=experiment,
            faults=faults,
            clock="realtime" if args.realtime else None,
            seed=args.seed,
        )
        print(
            f"hil emulate: {len(spec.joints)} joint(s), clock {spec.clock}"
            + (f", experiment {experiment.name}" if experiment else "")
            + (
                " (the plant advances one period per CAN SYNC; use --realtime for a free-running "
                "testbed)"
                if spec.clock == "lockstep"
                else ""
            )
            + ". Ctrl-C to stop.",
            file=sys.stderr,
        )
    serve(spec)
    return EXIT_OK


def _load_attach(text: str) -> dict:
    path = Path(text)
    if path.exists():
        text = path.read_text().splitlines()[0]
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ConfigError(f"--attach: not the JSON line `hil emulate` prints: {exc}") from None
    for key in ("dynamixel_port", "baudrate", "can"):
        if key not in data:
            raise ConfigError(f"--attach: the JSON line has no {key!r}")
    return data


# --- hil run ------------------------------------------------------------------------------


def _connection_args(args: argparse.Namespace) -> dict:
    return {
        "port": args.port,
        "baudrate": args.baudrate,
        "can_interface": args.can_interface,
        "can_channel": args.can_channel,
    }


def cmd_run(args: argparse.Namespace) -> int:
    from hil.runner import StopFlag
    from hil.session import Session, SessionError
    from hil.supervisor import ReferenceOutsideLimits

    config = load_config(args.config)
    if args.composition is not None:
        controller_section = dataclasses.replace(config.controller, composition=args.composition)
        config = config.with_overrides(controller=controller_section)
    if args.current_guard is not None:
        safety = dataclasses.replace(config.safety, current_guard=args.current_guard == "on")
        config = config.with_overrides(safety=safety)
    faults, overruns = parse_injections(args.inject)
    overrides = {k: v for k, v in _connection_args(args).items() if v}
    if args.attach and args.emulate:
        raise ConfigError(
            "--attach and --emulate exclude each other: attach to a running "
            "`hil emulate`, or let `hil run` start its own"
        )
    if overrides and args.config is None and not args.attach:
        raise ConfigError(
            f"{', '.join('--' + k.replace('_', '-') for k in overrides)} points a hardware "
            "configuration at other ports: give --config FILE (or --attach for an emulator)"
        )
    if args.experiment is None:
        ignored = [
            option
            for option, given in (
                ("--controller", args.controller is not None),
                ("--kdist", args.kdist is not None),
                ("--composition", args.composition is not None),
                ("--duration", args.duration is not None),
                ("--reboot-first", args.reboot_first),
            )
            if given
        ]
        if ignored:
            raise ConfigError(
                f"{', '.join(ignored)} apply to one experiment; the comparison (no experiment) "
                "runs its own plan: name an experiment (contact or impact)"
            )
    embedded = args.config is None or args.emulate
    if args.attach and embedded and args.config is None:
        embedded = False
    if args.experiment is None and not embedded and args.attach is None:
        raise ConfigError(
            "the comparison drives `pid` into the block until the actuator's overload "
            "protection trips: it runs only on an emulated testbed (no --config, --emulate, or "
            "--attach). On hardware, run one experiment at a time: hil run contact --config ..."
        )
    if faults and not embedded:
        raise ConfigError(
            "--inject of an emulator fault needs the embedded emulator (no --config, or "
            "--emulate); for a separate `hil emulate`, pass --inject to it"
        )
    if args.kdist is not None and args.kdist < 0:
        raise ConfigError(f"--kdist must be >= 0, got {args.kdist}")
    if args.duration is not None and args.duration <= 0:
        raise ConfigError(f"--duration must be > 0, got {args.duration}")
    attach = _load_attach(args.attach) if args.attach else None
    session = Session(
        config,
        embedded=embedded,
        realtime=args.realtime,
        attach=attach,
        connection_overrides=_connection_args(args),
        seed=args.seed,
        out_root=args.out,
        plots=not args.no_plots,
        json_output=args.json,
    )
    experiment = get_experiment(args.experiment) if args.experiment else None
    stop = StopFlag()
    stop.install()
    try:
        if experiment is None:
            result = session.run_comparison(
                faults=faults,
                overruns=overruns,
                current_guard=args.current_guard == "on",
                stop=stop,
            )
        else:
            controller = args.controller or config.controller.name
            kdist = args.kdist if args.kdist is not None else config.controller.kdist
            result = session.run_one(
                experiment,
                controller,
                kdist,
                faults=faults,
                overruns=overruns,
                duration_s=args.duration,
                reboot_first=args.reboot_first,
                stop=stop,
            )
    except SessionError as exc:
        print(f"hil run: {exc}", file=sys.stderr)
        return EXIT_FAILED
    except ReferenceOutsideLimits as exc:
        print(f"hil run: {exc}", file=sys.stderr)
        return EXIT_USAGE
    finally:
        stop.restore()
    return EXIT_OK if result.ok else EXIT_FAILED


# --- hil scan / hil reboot ----------------------------------------------------------------

SCAN_BAUDRATES = (3_000_000, 4_000_000, 1_000_000, 2_000_000, 57_600, 115_200, 9_600)


def cmd_scan(args: argparse.Namespace) -> int:
    from drivers.dynamixel import scan
    from drivers.joint_bus import BusError

    bauds = (args.baudrate,) if args.baudrate else SCAN_BAUDRATES
    found_any: list[dict] = []
    for baud in bauds:
        try:
            devices = scan(args.port, baud)
        except BusError as exc:
            print(f"hil scan: {exc}", file=sys.stderr)
            return EXIT_FAILED
        except ValueError as exc:
            print(f"hil scan: {exc}", file=sys.stderr)
            return EXIT_USAGE
        if not args.json:
            print(f"{args.port} at {baud} bps: {len(devices)} device(s)")
        for device in devices:
            row = {
                "id": device.dxl_id,
                "model_number": device.model_number,
                "model": device.model_name,
                "firmware": device.firmware_version,
                "baudrate": baud,
            }
            found_any.append(row)
            if not args.json:
                print(
                    f"  ID {device.dxl_id:3d}  {device.model_name} (model {device.model_number}), "
                    f"firmware {device.firmware_version}"
                )
        if devices and not args.baudrate:
            break  # devices on one line share a baud: stop at the first that answers
    if args.json:
        print(json.dumps({"port": args.port, "devices": found_any}))
    elif not found_any:
        print(
            "no device answered (check power, wiring, the baud rate, and that no other program "
            "has the port open)"
        )
    return EXIT_OK


def cmd_reboot(args: argparse.Namespace) -> int:
    """REBOOT every configured actuator, report what each says afterwards; torque stays off."""
    from drivers.dynamixel import DynamixelChain
    from drivers.joint_bus import BusError, HardwareError
    from hil.hardware import Connection, bus_config

    config = load_config(args.config)
    connection = (
        Connection.from_endpoints(_load_attach(args.attach))
        if args.attach
        else Connection.from_config(config)
    ).with_overrides(**_connection_args(args))
    chain_config = bus_config(config, connection).dynamixel
    chain = DynamixelChain(chain_config)
    results: dict[int, str] = {}
    try:
        chain.open(allow_torque_off=True)
        chain.disable()
        for dxl_id, status in chain.reboot().items():
            results[dxl_id] = HardwareError.describe(status.bits)
    except BusError as exc:
        print(f"hil reboot: {exc}", file=sys.stderr)
        return EXIT_FAILED
    finally:
        chain.close()
    if args.json:
        print(json.dumps({"rebooted": results}))
    else:
        for dxl_id, text in results.items():
            print(f"ID {dxl_id}: rebooted; hardware error status now: {text}; torque off")
    return EXIT_OK if all(text == "none" for text in results.values()) else EXIT_FAILED
