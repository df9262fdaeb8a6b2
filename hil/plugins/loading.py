"""Where a plug-in is, and its class loaded from there (see the package docstring).

A target is the canonical form of where a class is: "package.module:Class", or
"file:/absolute/path.py:Class" for a file (loaded once as a module of its own, registered in
sys.modules so that a forked worker and pickle find its classes). A fresh process loads the
same target again.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import keyword
import sys
from importlib.metadata import entry_points
from pathlib import Path
from types import ModuleType

_LOADED: dict[str, object] = {}  # target -> class


class PluginError(ValueError):
    """A plug-in cannot be found or imported: the message says which and why (the CLI exits 2
    with it, before anything is sent)."""


def entry_point_target(group: str, name: str) -> str | None:
    """The target of an installed package's entry point `name` in `group`, or None."""
    for ep in entry_points(group=group):
        if ep.name == name:
            return ep.value
    return None


def target_of(spec: str) -> str:
    """`spec` ("path/to/file.py:Class" or "package.module:Class") as a target; a file must
    exist."""
    if spec.startswith("file:"):
        return spec
    where, _, name = spec.rpartition(":")
    if not where:
        raise PluginError(f"{spec!r}: give path/to/file.py:Class or package.module:Class")
    if where.endswith(".py") or "/" in where or "\\" in where:
        path = Path(where).expanduser()
        if not path.is_file():
            raise PluginError(f"{spec}: no such file {where}")
        return f"file:{path.resolve()}:{name}"
    return spec


def class_from_target(target: str, spec: str) -> object:
    """What `target` names (a class, as the registry will check); `spec` is what the user
    typed, for the messages."""
    cached = _LOADED.get(target)
    if cached is not None:
        return cached
    where, _, name = target.rpartition(":")
    if not name.isidentifier() or keyword.iskeyword(name):
        raise PluginError(f"{spec}: {name!r} is not a class name")
    if where.startswith("file:"):
        module = _import_file(where[len("file:") :], spec)
    else:
        try:
            module = importlib.import_module(where)
        except Exception as exc:  # noqa: BLE001 - any error of the user's module, said
            raise PluginError(
                f"{spec}: cannot import {where}: {type(exc).__name__}: {exc}"
            ) from None
    found = getattr(module, name, None)
    if found is None:
        classes = sorted(
            n
            for n, v in vars(module).items()
            if isinstance(v, type) and not n.startswith("_") and v.__module__ == module.__name__
        )
        raise PluginError(
            f"{spec}: {where.removeprefix('file:')} has no {name}"
            + (f" (its classes: {', '.join(classes)})" if classes else "")
        )
    _LOADED[target] = found
    return found


def _import_file(path: str, spec: str) -> ModuleType:
    digest = hashlib.sha1(path.encode()).hexdigest()[:10]
    module_name = f"hil_plugin_{Path(path).stem}_{digest}"
    if module_name in sys.modules:
        return sys.modules[module_name]
    loader_spec = importlib.util.spec_from_file_location(module_name, path)
    if loader_spec is None or loader_spec.loader is None:
        raise PluginError(f"{spec}: {path} is not a Python file")
    module = importlib.util.module_from_spec(loader_spec)
    sys.modules[module_name] = module
    try:
        loader_spec.loader.exec_module(module)
    except Exception as exc:  # noqa: BLE001 - any error of the user's file, said with its line
        del sys.modules[module_name]
        raise PluginError(
            f"{spec}: importing {path}{_line_of(exc, path)} failed: {type(exc).__name__}: {exc}"
        ) from None
    return module


def _line_of(exc: BaseException, path: str) -> str:
    if isinstance(exc, SyntaxError) and exc.lineno:
        return f" (line {exc.lineno})"
    line, tb = None, exc.__traceback__
    while tb is not None:
        if tb.tb_frame.f_code.co_filename == path:
            line = tb.tb_lineno
        tb = tb.tb_next
    return f" (line {line})" if line else ""
