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

Parallel workers (pytest-xdist, `-n 2 --dist loadgroup`, as the README's test command runs
the suite): a test module stays on one worker (its module-scoped emulators are built once),
the modules that start Ray share one worker (two Ray clusters on two cores starve each other),
and the `timing` tests run in a second, serial pass (`-m timing`), where no other test loads
the machine.
"""

from __future__ import annotations

from pathlib import Path

import pytest

_TESTS = Path(__file__).parent
_E2E = _TESTS / "e2e"
# Modules that start a Ray cluster: on one xdist worker, one after the other.
_RAY_MODULES = frozenset({"test_sweep_ray.py", "test_sweep_interrupt.py"})


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--hardware-config",
        default=None,
        help="configuration file of a real testbed: runs the tests marked `hardware`",
    )


# tryfirst: xdist's worker names each item by its group in this same hook; after it, a group
# added here would not reach the scheduler (a module's tests went to both workers, each building
# the module's fixtures: the legs' twin was fitted twice at once)
@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    hardware = config.getoption("--hardware-config")
    skip_hardware = pytest.mark.skip(reason="needs a real testbed: --hardware-config FILE")
    for item in items:
        if _E2E in Path(str(item.fspath)).parents:
            item.add_marker(pytest.mark.subprocess)
        if "hardware" in item.keywords and not hardware:
            item.add_marker(skip_hardware)
        module = Path(str(item.fspath))
        group = "ray" if module.name in _RAY_MODULES else str(module.relative_to(_TESTS))
        item.add_marker(pytest.mark.xdist_group(group))
