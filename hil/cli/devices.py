"""`hil scan` and `hil reboot`: the Dynamixel devices on a port (each ID with its model, as it
answers PING: a chain may mix models), and clearing their faults."""

from __future__ import annotations

import argparse
import sys

from hil.cli.common import checked_config, connection_overrides, load_attach
from hil.cli.exit_codes import ExitCode
from hil.config import ConfigError
from hil.output.progress import Progress
from hil.output.strict_json import dumps

SCAN_BAUDRATES = (3_000_000, 4_000_000, 1_000_000, 2_000_000, 57_600, 115_200, 9_600)


def cmd_scan(args: argparse.Namespace) -> int:
    from drivers.dynamixel import MODELS, ScanProgress, scan
    from drivers.dynamixel.port import sdk_accepts_baudrate
    from drivers.joint_bus import BusError

    if args.baudrate is not None and not (
        args.baudrate > 0 and sdk_accepts_baudrate(args.baudrate)
    ):
        raise ConfigError(
            f"--baudrate: {args.baudrate} bit/s is not a rate dynamixel-sdk can set (e.g. "
            f"{', '.join(str(b) for b in sorted(SCAN_BAUDRATES))})"
        )
    bauds = (args.baudrate,) if args.baudrate else SCAN_BAUDRATES
    found: list[dict] = []
    # A bar over the baud rates (a one-by-one PING of every ID moves it within one), on a
    # terminal only; the per-baud lines stay.
    with Progress(len(bauds), unit="bauds", desc=f"scan {args.port}") as bar:
        for number, baud in enumerate(bauds):
            bar.update_to(number, f"{baud} bps")

            def pinged(step: ScanProgress, number: int = number) -> None:
                if step.pings_planned:
                    bar.update_to(number + step.pings_done / step.pings_planned)

            try:
                devices = scan(args.port, baud, progress=pinged)
            except BusError as exc:
                print(f"hil scan: {exc}", file=sys.stderr)
                return ExitCode.FAILED
            except ValueError as exc:
                print(f"hil scan: {exc}", file=sys.stderr)
                return ExitCode.USAGE
            if not args.json:
                bar.write(f"{args.port} at {baud} bps: {len(devices)} device(s)", sys.stdout)
            for device in devices:
                found.append(
                    {
                        "id": device.dxl_id,
                        "model_number": device.model_number,
                        "model": device.model_name,
                        "supported": device.model_number in MODELS,  # the driver drives it
                        "firmware": device.firmware_version,
                        "baudrate": baud,
                    }
                )
                if not args.json:
                    bar.write(
                        f"  ID {device.dxl_id:3d}  {device.model_name} (model "
                        f"{device.model_number}), firmware {device.firmware_version}",
                        sys.stdout,
                    )
            if devices and not args.baudrate:
                break  # devices on one line share a baud: stop at the first that answers
    if args.json:
        print(dumps({"port": args.port, "devices": found}))
    elif not found:
        print(
            "no device answered (check power, wiring, the baud rate, and that no other program "
            "has the port open)"
        )
    return ExitCode.OK


def cmd_reboot(args: argparse.Namespace) -> int:
    """REBOOT every configured actuator, report what each says afterwards; torque stays off."""
    from drivers.dynamixel import DynamixelChain, HardwareError
    from drivers.joint_bus import BusError
    from hil.wiring import Connection, bus_config

    config = checked_config(args.config)
    connection = (
        Connection.from_endpoints(load_attach(args.attach), config)
        if args.attach
        else Connection.from_config(config)
    ).with_overrides(**connection_overrides(args).given)
    results: dict[int, str] = {}
    for chain_config in bus_config(config, connection).chains:
        chain = DynamixelChain(chain_config)
        try:
            chain.open(allow_torque_off=True)
            chain.disable()
            for dxl_id, status in chain.reboot().items():
                results[dxl_id] = HardwareError.describe(status.bits)
        except BusError as exc:
            print(f"hil reboot: {chain_config.port}: {exc}", file=sys.stderr)
            return ExitCode.FAILED
        except ValueError as exc:
            raise ConfigError(str(exc)) from exc
        finally:
            chain.close()
    if args.json:
        print(dumps({"rebooted": results}))
    else:
        for dxl_id, text in results.items():
            print(f"ID {dxl_id}: rebooted; hardware error status now: {text}; torque off")
    return ExitCode.OK if all(text == "none" for text in results.values()) else ExitCode.FAILED
