"""The layout's rules, checked on the source: who may import whom, no import circle, plotting
without device libraries, functions a reader can take in."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("controller", "drivers", "sim_backend", "hil")
DEVICE_LIBRARIES = ("mujoco", "dynamixel_sdk", "can", "canopen", "serial")
# hil's sub-packages, each allowed to import only those listed (besides itself).
HIL_LAYERS = {
    "hil.vocabulary": set(),
    "hil.plugins": set(),
    "hil.config": {"hil.vocabulary"},
    "hil.output": {"hil.vocabulary"},
    "hil.experiments": {
        "hil.vocabulary",
        "hil.config",
        "hil.output",
        "hil.identify",
        "hil.plugins",
    },
    # the robots, one folder each, and their registry: above what a robot's profile holds
    "hil.robots": {
        "hil.vocabulary",
        "hil.config",
        "hil.output",
        "hil.experiments",
        "hil.plugins",
    },
    "hil.safety": {"hil.vocabulary", "hil.config"},
    "hil.controllers": {
        "hil.vocabulary",
        "hil.config",
        "hil.experiments",
        "hil.plugins",
        "hil.robots",
    },
    "hil.wiring": {"hil.vocabulary", "hil.config", "hil.experiments", "hil.robots"},
    "hil.loop": {
        "hil.vocabulary",
        "hil.controllers",
        "hil.config",
        "hil.output",
        "hil.experiments",
        "hil.safety",
        "hil.wiring",
        "hil.robots",
    },
    "hil.identify": {"hil.vocabulary", "hil.output"},
    "hil.bringup": {"hil.vocabulary", "hil.config"},
    "hil.render": {"hil.vocabulary", "hil.output", "hil.experiments", "hil.robots"},
    "hil.session": {
        "hil.vocabulary",
        "hil.controllers",
        "hil.config",
        "hil.output",
        "hil.experiments",
        "hil.robots",
        "hil.safety",
        "hil.wiring",
        "hil.loop",
        "hil.render",
    },
    "hil.bench": {
        "hil.vocabulary",
        "hil.controllers",
        "hil.config",
        "hil.output",
        "hil.experiments",
        "hil.robots",
        "hil.wiring",
        "hil.loop",
    },
    "hil.sweep": {
        "hil.vocabulary",
        "hil.controllers",
        "hil.config",
        "hil.output",
        "hil.experiments",
        "hil.robots",
        "hil.wiring",
        "hil.loop",
        "hil.session",
    },
    "hil.twin": {
        "hil.vocabulary",
        "hil.controllers",
        "hil.config",
        "hil.output",
        "hil.experiments",
        "hil.wiring",
        "hil.identify",
        "hil.robots",
        "hil.session",
        "hil.sweep",  # the fit's replays on Ray go the sweeps' way (hil/twin/executor.py)
    },
    "hil.api": {
        "hil.vocabulary",
        "hil.controllers",
        "hil.config",
        "hil.output",
        "hil.experiments",
        "hil.robots",
        "hil.safety",
        "hil.wiring",
        "hil.loop",
        "hil.session",
    },
    "hil.cli": {
        "hil.plugins",
        "hil.vocabulary",
        "hil.controllers",
        "hil.config",
        "hil.output",
        "hil.experiments",
        "hil.robots",
        "hil.safety",
        "hil.wiring",
        "hil.loop",
        "hil.session",
        "hil.bench",
        "hil.identify",
        "hil.bringup",
        "hil.sweep",
        "hil.twin",
        "hil.render",
    },
}


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _imports() -> dict[str, set[str]]:
    """Module -> the modules of ours it imports (anywhere in the file)."""
    graph: dict[str, set[str]] = {}
    for package in PACKAGES:
        for path in (ROOT / package).rglob("*.py"):
            name = _module_name(path)
            found: set[str] = set()
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.Import):
                    found |= {alias.name for alias in node.names}
                elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                    found.add(node.module)
            graph[name] = {m for m in found if m.split(".")[0] in PACKAGES}
    return graph


GRAPH = _imports()


def _layer(module: str) -> str:
    parts = module.split(".")
    return ".".join(parts[:2]) if parts[0] == "hil" and len(parts) > 1 else parts[0]


def test_the_four_packages_import_one_way() -> None:
    allowed = {
        "controller": {"controller"},
        "drivers": {"drivers"},
        "sim_backend": {"sim_backend"},
    }
    for module, imported in GRAPH.items():
        top = module.split(".")[0]
        if top in allowed:
            bad = {m for m in imported if m.split(".")[0] not in allowed[top]}
            assert not bad, f"{module} imports {sorted(bad)}"


def test_hil_sub_packages_import_only_downwards() -> None:
    for module, imported in GRAPH.items():
        if not module.startswith("hil.") or _layer(module) == "hil.__main__":
            continue
        layer = _layer(module)
        assert layer in HIL_LAYERS, f"{module}: a sub-package the layout does not know"
        for target in imported:
            if not target.startswith("hil."):
                continue
            other = _layer(target)
            assert other == layer or other in HIL_LAYERS[layer], f"{module} imports {target}"


def test_there_is_no_import_circle() -> None:
    modules = set(GRAPH)

    def resolve(name: str) -> str | None:
        while name and name not in modules:
            name = name.rpartition(".")[0]
        return name or None

    edges = {
        m: {r for t in targets if (r := resolve(t)) and r != m} for m, targets in GRAPH.items()
    }
    visiting: list[str] = []
    done: set[str] = set()

    def visit(module: str) -> None:
        if module in done:
            return
        assert module not in visiting, " -> ".join([*visiting[visiting.index(module) :], module])
        visiting.append(module)
        for target in sorted(edges[module]):
            # a package's __init__ importing its own modules is not a circle
            if not target.startswith(module + "."):
                visit(target)
        visiting.pop()
        done.add(module)

    for module in sorted(modules):
        visit(module)


@pytest.mark.parametrize("module", ["hil.output", "hil.experiments", "hil.config"])
def test_reading_and_plotting_runs_loads_no_device_library(module: str) -> None:
    code = (
        f"import sys, {module}, hil.output.plots, hil.output.report; "
        f"print(sorted(m for m in {DEVICE_LIBRARIES!r} if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_no_function_in_hil_is_longer_than_80_lines() -> None:
    long = []
    for path in (ROOT / "hil").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                length = node.end_lineno - node.lineno + 1
                if length > 80:
                    long.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.name} ({length})")
    assert not long, long


# Where a robot's name may be written as a string: its own folder and the registry
# (hil/robots/), and the enum that defines the names (hil.vocabulary.Robot).
ROBOT_NAME_HOMES = ("hil/robots/", "hil/vocabulary.py")


def _robot_names() -> set[str]:
    from hil.vocabulary import _TESTBED_OLD_NAME, Robot

    return {str(robot) for robot in Robot} | {_TESTBED_OLD_NAME}


def test_no_robot_is_named_by_a_string_outside_its_folder_and_the_registry() -> None:
    names = _robot_names()
    found = []
    for package in PACKAGES:
        for path in (ROOT / package).rglob("*.py"):
            where = str(path.relative_to(ROOT))
            if where.startswith(ROBOT_NAME_HOMES):
                continue
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.Constant) and node.value in names:
                    found.append(f"{where}:{node.lineno} {node.value!r}")
    assert not found, (
        "a robot named by a string (compare hil.vocabulary.Robot, or put it in the robot's "
        f"folder, hil/robots/<name>/): {found}"
    )
