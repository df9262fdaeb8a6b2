"""Test suite layout (mirrors the packages) and markers.

    tests/controller/   the paper's math, checked against analysis (no bus)
    tests/drivers/      our drivers on the unmodified SDKs, against the emulated devices
    tests/sim_backend/  the emulated devices, buses and plant
    tests/hil/          the loop, the supervisor, configuration, output - mostly on the
                        in-process joint bus (hil.wiring.in_process), in milliseconds
    tests/e2e/          the whole path: `hil emulate` in a child process, pseudo-terminals,
                        the real drivers and the CLI (marked `subprocess`)
    tests/support/      helpers shared by the tests (the run loader, the safety rig)

Markers: `slow` (more than ~5 s), `subprocess` (starts `hil emulate` or another process),
`timing` (asserts wall-clock figures: relaxed on a loaded machine), `hardware` (needs the real
testbed: run with --hardware-config FILE; skipped otherwise).
"""

from __future__ import annotations

from pathlib import Path

import pytest

_E2E = Path(__file__).parent / "e2e"


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--hardware-config",
        default=None,
        help="configuration file of a real testbed: runs the tests marked `hardware`",
    )


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    hardware = config.getoption("--hardware-config")
    skip_hardware = pytest.mark.skip(reason="needs a real testbed: --hardware-config FILE")
    for item in items:
        if _E2E in Path(str(item.fspath)).parents:
            item.add_marker(pytest.mark.subprocess)
        if "hardware" in item.keywords and not hardware:
            item.add_marker(skip_hardware)
