"""`python -m sim_backend --spec-file SPEC.json`: serve the emulated hardware of a spec (as
`sim_backend.spec.spec_to_json` wrote it) on its buses until SIGINT / SIGTERM.

What `hil run` starts for its embedded emulator: the same server as `hil emulate`, without
importing the host's packages (the child starts in about a third of the time)."""

from __future__ import annotations

import argparse
from pathlib import Path

from sim_backend.server import serve
from sim_backend.spec import spec_from_json


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m sim_backend", description=__doc__)
    parser.add_argument("--spec-file", type=Path, required=True, help="the spec, as JSON")
    args = parser.parse_args(argv)
    serve(spec_from_json(args.spec_file.read_text()))


if __name__ == "__main__":
    main()
