"""`python -m sim_backend --spec-file SPEC.json`: serve the emulated hardware of a spec (as
`sim_backend.spec_json.spec_to_json` wrote it) on its buses until SIGINT / SIGTERM.

`python -m sim_backend --fork-server FD`: the fork server `hil run` starts its embedded
emulators from (sim_backend/fork_server.py): each one the same server as `hil emulate`, without
importing the host's packages or, after the first, even sim_backend's."""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
from pathlib import Path

from sim_backend.server import serve_spec_file


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m sim_backend", description=__doc__)
    what = parser.add_mutually_exclusive_group(required=True)
    what.add_argument("--spec-file", type=Path, help="the spec, as JSON")
    what.add_argument(
        "--fork-server", type=int, metavar="FD", help="fork emulators on requests on socket FD"
    )
    args = parser.parse_args(argv)
    if args.fork_server is not None:
        from sim_backend.fork_server import serve_forks

        return serve_forks(args.fork_server)
    return serve_spec_file(str(args.spec_file))


if __name__ == "__main__":
    status = main()
    # Everything is released by now (the ptys closed, the last line flushed): skip the
    # interpreter's teardown of numpy, MuJoCo and the rest, ~50 ms of every run's end.
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError):  # nobody reads any more: fine
            stream.flush()
    os._exit(status)
