"""`hil emulate`: serve the emulated testbed on its buses until Ctrl-C / SIGTERM."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from hil.cli.common import checked_config, parse_injections
from hil.cli.exit_codes import ExitCode
from hil.config import ConfigError
from hil.robots import get_experiment
from hil.vocabulary import EmulatorClock
from hil.wiring.emulation import emulator_spec, spec_from_json


def cmd_emulate(args: argparse.Namespace) -> int:
    from sim_backend.server import serve

    world: dict[str, object] = {}
    if args.spec_file is not None:  # from `hil run`'s embedded emulator
        spec = spec_from_json(Path(args.spec_file).read_text())
    else:
        config = checked_config(args.config, args.robot, args.experiment)
        if args.seed is not None:
            config = config.changed("emulator", seed=args.seed, option="--seed")
        experiment = get_experiment(args.experiment) if args.experiment else None
        faults, overruns = parse_injections(args.inject)
        if overruns:
            raise ConfigError("overrun is a fault of the loop: inject it with `hil run --inject`")
        spec = emulator_spec(
            config,
            experiment=experiment,
            faults=faults,
            clock=EmulatorClock.REALTIME if args.realtime else None,
        )
        # what a run attaching to it checks: is this the world of its experiment?
        world = {"experiment": experiment.name if experiment else None}
        lockstep_note = (
            " (the plant advances one period per CAN SYNC; use --realtime for a free-running "
            "testbed)"
        )
        print(
            f"hil emulate: {len(spec.joints)} joint(s), clock {spec.clock}"
            + (f", experiment {experiment.name}" if experiment else "")
            + (lockstep_note if spec.clock == EmulatorClock.LOCKSTEP else "")
            + ". Ctrl-C to stop.",
            file=sys.stderr,
        )
    serve(spec, extra=world)
    return ExitCode.OK
