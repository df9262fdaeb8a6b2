"""The controllers `hil` knows by name, and the plug-ins it loads by where they are.

`--controller NAME` (or `[controller] name`) is one of:
    a registry name       one of `BUILT_IN` below, or of an installed package's entry points in
                          the group `flexjoint_hil.controllers` (`name = "package.module:Class"`
                          in its pyproject's `[project.entry-points."flexjoint_hil.controllers"]`)
    path/to/file.py:Class a class in a Python file (loaded as a module of its own)
    package.module:Class  a class in an importable module
The class must implement the contract (hil/controllers/contract.py). Its parameters come from
the configuration's `[controller.params]`, validated by its `Params`.

Adding a built-in controller is one module and one line of `BUILT_IN`.
"""

from __future__ import annotations

import inspect
from collections.abc import Mapping
from importlib.metadata import entry_points
from typing import Any

from pydantic import ValidationError

from hil.controllers.contract import Controller, ControllerParams, ControllerSetup
from hil.controllers.paper import PaperController
from hil.plugins import PluginError, class_from_target, entry_point_target, target_of
from hil.vocabulary import ControllerChoice, ControllerRef

# name -> "module:Class", one line per built-in controller
BUILT_IN: dict[str, str] = {
    "pid": "hil.controllers.paper:Pid",
    "gc": "hil.controllers.paper:Gc",
    "gc+lqr": "hil.controllers.paper:GcLqr",
    "gc+lqr+dob": "hil.controllers.paper:GcLqrDob",
}
ENTRY_POINT_GROUP = "flexjoint_hil.controllers"


class ControllerLoadError(ValueError):
    """A controller cannot be found, imported, or does not keep the contract: the message says
    which and why (the CLI exits 2 with it, before anything is sent)."""


def available() -> list[str]:
    """The registry's names: the built-in ones, then the installed packages'."""
    return [*BUILT_IN, *(ep.name for ep in entry_points(group=ENTRY_POINT_GROUP))]


def resolve(spec: str) -> ControllerRef:
    """The controller `spec` names (see the module docstring), loaded and checked."""
    spec = spec.strip()
    try:
        target = _target(spec)
    except PluginError as exc:
        raise ControllerLoadError(str(exc)) from None
    cls = _load(target, spec)
    _check_contract(cls, spec)
    if isinstance(cls, type) and issubclass(cls, PaperController):
        return ControllerRef.of_paper(cls.kind)
    return ControllerRef(
        name=spec if ":" not in spec else cls.__name__,
        spec=target,
        uses_kdist=cls.uses_kdist,
        needs_link_angle=cls.needs_link_angle,
    )


def controller_class(ref: ControllerRef) -> type[Controller]:
    """The class of a resolved controller (loaded again in a fresh process)."""
    return _load(ref.spec if ":" in ref.spec else _target(ref.spec), ref.spec)


def controller_params(
    ref: ControllerRef, choice: ControllerChoice, table: Mapping[str, Any]
) -> ControllerParams:
    """The controller's parameters: the paper's from the run's choice, a plug-in's from
    `[controller.params]` (`table`), validated by its `Params`; a ControllerLoadError names the
    key that is wrong."""
    cls = controller_class(ref)
    if issubclass(cls, PaperController):
        if table:
            raise ControllerLoadError(
                f"[controller.params]: {ref.name} takes its parameters from [controller] "
                f"(not {sorted(table)})"
            )
        return cls.params_of(choice)
    try:
        return cls.Params.model_validate(dict(table))
    except ValidationError as exc:
        problems = "; ".join(
            f"[controller.params] {'.'.join(str(p) for p in error['loc']) or '(table)'}: "
            f"{error['msg']}"
            for error in exc.errors()
        )
        raise ControllerLoadError(f"{ref.name} ({ref.spec}): {problems}") from None


def build(choice: ControllerChoice, setup: ControllerSetup, table: Mapping[str, Any]) -> Controller:
    """The chosen controller for this run's robot."""
    ref = choice.ref
    return controller_class(ref)(setup, controller_params(ref, choice, table))


# --- finding the class ----------------------------------------------------------------------
def _target(spec: str) -> str:
    """`spec` as a target ("module:Class" or "file:/abs/path.py:Class")."""
    if spec in BUILT_IN:
        return BUILT_IN[spec]
    if ":" in spec:
        return target_of(spec)
    target = entry_point_target(ENTRY_POINT_GROUP, spec)
    if target is None:
        raise ControllerLoadError(
            f"unknown controller {spec!r}: give one of {available()}, or a plug-in as "
            "path/to/file.py:Class or package.module:Class"
        )
    return target


def _load(target: str, spec: str) -> type[Controller]:
    try:
        return class_from_target(target, spec)  # type: ignore[return-value]
    except PluginError as exc:
        raise ControllerLoadError(str(exc)) from None


def _check_contract(cls: object, spec: str) -> None:
    if not (isinstance(cls, type) and issubclass(cls, Controller)):
        raise ControllerLoadError(
            f"{spec}: {getattr(cls, '__name__', cls)!r} is not a controller: subclass "
            "hil.Controller (hil/controllers/contract.py)"
        )
    if inspect.isabstract(cls):
        missing = ", ".join(f"{m}()" for m in sorted(cls.__abstractmethods__))
        raise ControllerLoadError(f"{spec}: {cls.__name__} does not define {missing}")
    if not (isinstance(cls.Params, type) and issubclass(cls.Params, ControllerParams)):
        raise ControllerLoadError(
            f"{spec}: {cls.__name__}.Params must subclass hil.ControllerParams"
        )
    names = cls.term_names
    if not isinstance(names, tuple) or not all(
        isinstance(n, str) and n.isidentifier() for n in names
    ):
        raise ControllerLoadError(
            f"{spec}: {cls.__name__}.term_names must be a tuple of identifiers, got {names!r}"
        )
    if len(set(names)) != len(names):
        raise ControllerLoadError(f"{spec}: {cls.__name__}.term_names repeats a name")
