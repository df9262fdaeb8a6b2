"""`python -m hil ...` is the `hil` command."""

import sys

if sys.argv[1:3] == ["emulate", "--spec-file"] and len(sys.argv) == 4:
    # `hil run`'s embedded emulator (hil/wiring/emulation.py): the spec is already checked, so
    # it is served without loading the CLI (seconds of imports: experiments, plots, scipy)
    from sim_backend.server import serve_spec_file

    raise SystemExit(serve_spec_file(sys.argv[3]))

from hil.cli import main

raise SystemExit(main())
