"""The emulator server (`sim_backend.server.serve`) in a child process, for tests and tools.

    with emulator_process(spec) as emulator:
        emulator.endpoints["dynamixel_port"], emulator.endpoints["can"]  # what serve() printed
    emulator.fault_counts   # its last line: how often each injected fault acted

The child is a fresh interpreter (`python -c`), given the spec pickled on its command line; it
is stopped with SIGTERM (then killed) when the block ends, and prints its fault counts then.
A separate process, because dynamixel-sdk busy-waits: an emulator thread in the host's
interpreter would be starved by the GIL.
"""

from __future__ import annotations

import contextlib
import json
import pickle
import selectors
import signal
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

from sim_backend.server import EmulatorSpec

_CHILD = (
    "import pickle, sys; from sim_backend.server import serve; "
    "serve(pickle.loads(bytes.fromhex(sys.argv[1])))"
)


@dataclass
class EmulatorProcess:
    """A running emulator child: its endpoints, and after the block its fault counts."""

    process: subprocess.Popen[str]
    endpoints: dict[str, Any]
    fault_counts: dict[str, Any] = field(default_factory=dict)


@contextlib.contextmanager
def emulator_process(
    spec: EmulatorSpec, *, start_timeout_s: float = 30.0
) -> Iterator[EmulatorProcess]:
    """Run `serve(spec)` in a child process for the duration of the block (see module doc)."""
    process = subprocess.Popen(
        # -P: the working directory is not put on the import path (see hil/wiring/emulation.py)
        [sys.executable, "-P", "-c", _CHILD, pickle.dumps(spec).hex()],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert process.stdout is not None
        with selectors.DefaultSelector() as selector:
            selector.register(process.stdout, selectors.EVENT_READ)
            if not selector.select(start_timeout_s):
                raise TimeoutError(f"the emulator did not start within {start_timeout_s} s")
        line = process.stdout.readline()
        if not line:
            raise RuntimeError(f"the emulator exited at start-up (exit code {process.wait()})")
        running = EmulatorProcess(process, json.loads(line))
        yield running
        process.send_signal(signal.SIGTERM)
        rest, _ = process.communicate(timeout=10.0)
        for extra in rest.splitlines():
            record = json.loads(extra)
            if "fault_counts" in record:
                running.fault_counts = record["fault_counts"]
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
