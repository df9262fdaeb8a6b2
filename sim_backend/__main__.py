"""`python -m sim_backend --spec-file SPEC.json`: serve the emulated hardware of a spec (as
`sim_backend.spec_json.spec_to_json` wrote it) on its buses until SIGINT / SIGTERM.

What `hil run` starts for its embedded emulator: the same server as `hil emulate`, without
importing the host's packages (the CLI's imports cost seconds of every run's start-up)."""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
from pathlib import Path

from sim_backend.server import serve_spec_file


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m sim_backend", description=__doc__)
    parser.add_argument("--spec-file", type=Path, required=True, help="the spec, as JSON")
    return serve_spec_file(str(parser.parse_args(argv).spec_file))


if __name__ == "__main__":
    status = main()
    # Everything is released by now (the ptys closed, the last line flushed): skip the
    # interpreter's teardown of numpy, MuJoCo and the rest, ~50 ms of every run's end.
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError):  # nobody reads any more: fine
            stream.flush()
    os._exit(status)
