"""A sweep specification (TOML) and its plan: which runs, with which configuration changes.

    title = "..."
    experiments = ["impact"]                       # run at every point
    controllers = ["pid", "gc+lqr", "gc+lqr+dob@0.5", "gc+lqr+dob@1"]  # KIND[@KDIST][/READING]
    setup = "in_process"                           # or "embedded" (a `hil emulate` per run)
    model = "nominal"                              # or "plant" (see ModelFollows)
    seed = 0                                       # the emulator's seed of every run
    duration_s = 5.0                               # optional: shorten every run
    keep_logs = false                              # keep each run's directory (failed: always)
    [base]                                         # configuration changes before every point
    "safety.current_guard" = false
    [sampling]
    method = "grid"                                # or "monte-carlo" (count, seed)
    [[parameter]]
    name = "Kp"                                    # its column in results.csv
    targets = ["emulator.servo.position_gain_per_s"]   # section.key or emulator.plant/servo.key
    values = [5.0, 10.0, 20.0]                     # grid values, or the choices of a draw
    # or: relative = [0.7, 1.3] (factors of the configured value) or low/high, with
    #     points = N for a grid (log = true: spaced logarithmically) or drawn uniformly
    [maps]
    axes = ["Kp", "inertia"]                       # the two parameters a map is drawn over

A run is one (point, experiment, controller): hil/sweep/plan.py lists them.
"""

from __future__ import annotations

import enum
import itertools
import math
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from hil.config import ConfigError
from hil.robots import EXPERIMENTS
from hil.sweep.ranges import SpecError, check_range, whole_number
from hil.vocabulary import ControllerChoice, ControllerKind

SHIPPED_DIR = ("data", "sweeps")
Value = float | str | bool


class Sampling(enum.StrEnum):
    GRID = "grid"
    MONTE_CARLO = "monte-carlo"


class ModelFollows(enum.StrEnum):
    """What the controller's [model] is at each point."""

    NOMINAL = "nominal"  # the configuration's: the plant varies under a fixed model (robustness)
    PLANT = "plant"  # the plant's true figures (K, D, position gain, inertia, m r): as if
    # the joint had been identified


class SweepSetup(enum.StrEnum):
    IN_PROCESS = "in_process"
    EMBEDDED = "embedded"


@dataclass(frozen=True)
class SweepParameter:
    """One axis: a name, the configuration keys it sets, its values or its range."""

    name: str
    targets: tuple[str, ...]
    values: tuple[Value, ...] = ()
    low: float | None = None
    high: float | None = None
    points: int | None = None
    log: bool = False
    relative: tuple[float, float] | None = None  # factors of the configured value (resolved)

    def grid(self) -> tuple[Value, ...]:
        if self.values:
            return self.values
        assert self.low is not None and self.high is not None
        if self.points is None:
            raise SpecError(f"parameter {self.name!r}: a grid needs values or points")
        space = np.geomspace if self.log else np.linspace
        return tuple(float(v) for v in space(self.low, self.high, self.points))

    def draw(self, rng: np.random.Generator) -> Value:
        if self.values:
            return self.values[int(rng.integers(len(self.values)))]
        assert self.low is not None and self.high is not None
        if self.log:
            return float(math.exp(rng.uniform(math.log(self.low), math.log(self.high))))
        return float(rng.uniform(self.low, self.high))

    @property
    def numeric(self) -> bool:
        return all(isinstance(v, int | float) and not isinstance(v, bool) for v in self.values)


@dataclass(frozen=True)
class Task:
    """One run of the sweep (plain data: it travels to a Ray worker)."""

    run_id: str
    point_id: str
    values: dict[str, Value]  # by parameter name (the row's columns)
    targets: dict[str, Value]  # by configuration target (what the worker sets)
    experiment: str
    controller: str
    config_record: dict[str, Any] = field(repr=False)
    model: ModelFollows = ModelFollows.NOMINAL
    setup: SweepSetup = SweepSetup.IN_PROCESS
    seed: int = 0
    duration_s: float | None = None
    keep_log: bool = False

    @property
    def choice(self) -> ControllerChoice:
        return parse_controller(self.controller)


@dataclass(frozen=True)
class SweepSpec:
    name: str
    title: str
    experiments: tuple[str, ...]
    controllers: tuple[str, ...]
    parameters: tuple[SweepParameter, ...]
    sampling: Sampling = Sampling.GRID
    count: int = 0
    sample_seed: int = 0
    setup: SweepSetup = SweepSetup.IN_PROCESS
    model: ModelFollows = ModelFollows.NOMINAL
    seed: int = 0
    duration_s: float | None = None
    keep_logs: bool = False
    base: dict[str, Value] = field(default_factory=dict)
    map_axes: tuple[str, ...] = ()
    description: str = ""

    @property
    def parameter_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    def points(self) -> list[dict[str, Value]]:
        """Every point of the grid, or the Monte Carlo sample (reproducible from its seed)."""
        if self.sampling is Sampling.GRID:
            grids = [p.grid() for p in self.parameters]
            return [
                dict(zip(self.parameter_names, c, strict=True)) for c in itertools.product(*grids)
            ]
        rng = np.random.default_rng(self.sample_seed)
        return [{p.name: p.draw(rng) for p in self.parameters} for _ in range(self.count)]

    @property
    def axes(self) -> tuple[str, ...]:
        """The (at most two) parameters the maps are drawn over."""
        if self.map_axes:
            return self.map_axes
        return self.parameter_names[:2]


# --- controllers --------------------------------------------------------------------------------
def parse_controller(text: str) -> ControllerChoice:
    """'gc+lqr+dob@0.5/literal' -> ControllerChoice(GC_LQR_DOB, 0.5, 'literal')."""
    head, _, reading = text.partition("/")
    kind, _, kdist = head.partition("@")
    try:
        return ControllerChoice(
            ControllerKind(kind), float(kdist) if kdist else 0.0, reading or None
        )
    except ValueError as exc:
        raise SpecError(f"controller {text!r}: {exc} (write KIND[@KDIST][/READING])") from None


# --- reading a spec ----------------------------------------------------------------------------
def shipped_specs() -> dict[str, str]:
    """The specs shipped with the package: name -> TOML text."""
    folder = resources.files("hil").joinpath(*SHIPPED_DIR)
    return {
        entry.name.removesuffix(".toml"): entry.read_text()
        for entry in sorted(folder.iterdir(), key=lambda e: e.name)
        if entry.name.endswith(".toml")
    }


def load_spec(name_or_path: str) -> SweepSpec:
    """A TOML file, or the name of a shipped spec."""
    path = Path(name_or_path)
    if path.suffix == ".toml" or path.exists():
        try:
            text = path.read_text()
        except OSError as exc:
            raise SpecError(f"cannot read sweep spec {path}: {exc.strerror}") from None
        return parse_spec(text, path.stem)
    shipped = shipped_specs()
    if name_or_path not in shipped:
        raise SpecError(
            f"{name_or_path!r} is neither a TOML file nor a shipped spec ({sorted(shipped)})"
        )
    return parse_spec(shipped[name_or_path], name_or_path)


def parse_spec(text: str, name: str) -> SweepSpec:
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SpecError(f"sweep spec {name}: not valid TOML: {exc}") from None
    try:
        return _spec(raw, name)
    except (KeyError, TypeError, ValueError) as exc:
        if isinstance(exc, SpecError):
            raise SpecError(f"sweep spec {name}: {exc}") from None
        raise SpecError(f"sweep spec {name}: {type(exc).__name__}: {exc}") from None


_SPEC_KEYS = {
    "title", "description", "experiments", "controllers", "setup", "model", "seed",
    "duration_s", "keep_logs", "base", "sampling", "parameter", "maps",
}  # fmt: skip


def _spec(raw: dict[str, Any], name: str) -> SweepSpec:
    unknown = sorted(set(raw) - _SPEC_KEYS)
    if unknown:
        raise SpecError(f"unknown keys {unknown}")
    experiments = tuple(raw["experiments"])
    for experiment in experiments:
        if experiment not in EXPERIMENTS:
            raise SpecError(f"unknown experiment {experiment!r} ({sorted(EXPERIMENTS)})")
    controllers = tuple(raw["controllers"])
    for controller in controllers:
        parse_controller(controller)
    sampling = raw.get("sampling", {})
    parameters = tuple(_parameter(p) for p in raw.get("parameter", []))
    if not parameters:
        raise SpecError("no [[parameter]]")
    names = [p.name for p in parameters]
    if len(set(names)) != len(names):
        raise SpecError(f"parameter names repeat: {names}")
    spec = SweepSpec(
        name=name,
        title=str(raw.get("title", name)),
        description=str(raw.get("description", "")),
        experiments=experiments,
        controllers=controllers,
        parameters=parameters,
        sampling=Sampling(sampling.get("method", "grid")),
        count=whole_number(sampling.get("count", 0), "[sampling] count", 0),
        sample_seed=int(sampling.get("seed", 0)),
        setup=SweepSetup(raw.get("setup", "in_process")),
        model=ModelFollows(raw.get("model", "nominal")),
        seed=int(raw.get("seed", 0)),
        duration_s=float(raw["duration_s"]) if "duration_s" in raw else None,
        keep_logs=bool(raw.get("keep_logs", False)),
        base=dict(raw.get("base", {})),
        map_axes=tuple(raw.get("maps", {}).get("axes", ())),
    )
    _check(spec)
    return spec


_PARAMETER_KEYS = {
    "name",
    "targets",
    "target",
    "values",
    "low",
    "high",
    "points",
    "log",
    "relative",
}


def _parameter(raw: dict[str, Any]) -> SweepParameter:
    name = str(raw["name"])
    unknown = sorted(set(raw) - _PARAMETER_KEYS)
    if unknown:
        raise SpecError(f"parameter {name!r}: unknown keys {unknown}")
    targets = raw.get("targets", raw.get("target"))
    targets = (targets,) if isinstance(targets, str) else tuple(targets or ())
    if not targets:
        raise SpecError(f"parameter {name!r}: no targets")
    low, high = raw.get("low"), raw.get("high")
    relative = raw.get("relative")
    if "values" in raw and not raw["values"]:
        raise SpecError(f"parameter {name!r}: values is empty")
    if relative is not None:
        factors = tuple(float(f) for f in relative)
        if len(factors) != 2 or not 0 < factors[0] < factors[1]:
            raise SpecError(f"parameter {name!r}: relative = [low factor, high factor] > 0")
        relative = factors
    parameter = SweepParameter(
        name=name,
        targets=targets,
        values=tuple(raw.get("values", ())),
        low=None if low is None else float(low),
        high=None if high is None else float(high),
        points=raw.get("points"),
        log=bool(raw.get("log", False)),
        relative=relative,
    )
    check_range(parameter)
    return parameter


def _check(spec: SweepSpec) -> None:
    if spec.sampling is Sampling.MONTE_CARLO and spec.count < 1:
        raise SpecError("[sampling] monte-carlo needs count >= 1")
    for p in spec.parameters:
        if not p.values and p.relative is None and (p.low is None or p.high is None):
            raise SpecError(f"parameter {p.name!r}: give values, relative or low/high")
        if spec.sampling is Sampling.GRID and not p.values and p.points is None:
            raise SpecError(f"parameter {p.name!r}: a grid needs values or points")
    for axis in spec.axes:
        if axis not in spec.parameter_names:
            raise SpecError(f"[maps] axes: {axis!r} is not a parameter")
    if spec.duration_s is not None and not (math.isfinite(spec.duration_s) and spec.duration_s > 0):
        raise SpecError("duration_s must be a finite time > 0")


__all__ = [
    "ConfigError",
    "ModelFollows",
    "Sampling",
    "SpecError",
    "SweepParameter",
    "SweepSetup",
    "SweepSpec",
    "Task",
    "load_spec",
    "parse_controller",
    "parse_spec",
    "shipped_specs",
]
