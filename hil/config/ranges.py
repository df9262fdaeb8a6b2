"""A figure's whole range as the schema declares it, to say it in an error ("must be in
100 .. 1e+05", not only the side that was crossed) and to list every figure's range."""

from __future__ import annotations

import types
import typing
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

from pydantic import BaseModel
from pydantic.fields import FieldInfo


@dataclass(frozen=True)
class FigureRange:
    low: float | None
    high: float | None
    low_open: bool = False  # low itself is outside (gt, not ge)
    high_open: bool = False

    def __str__(self) -> str:
        low = "-inf" if self.low is None else _number(self.low)
        high = "inf" if self.high is None else _number(self.high)
        return f"{'(' if self.low_open else '['}{low}, {high}{')' if self.high_open else ']'}"


def _number(value: float) -> str:
    return str(value) if isinstance(value, int) else f"{value:g}"


def _constraints(metadata: list[Any]) -> FigureRange | None:
    found: dict[str, Any] = {}
    for item in metadata:
        for name in ("gt", "ge", "lt", "le"):
            value = getattr(item, name, None)
            if value is not None:
                found[name] = value
    if not found:
        return None
    return FigureRange(
        low=found.get("ge", found.get("gt")),
        high=found.get("le", found.get("lt")),
        low_open="gt" in found,
        high_open="lt" in found,
    )


def _inner(annotation: Any) -> tuple[Any, list[Any]]:
    """(the type without None and containers, the Annotated constraints met on the way)."""
    metadata: list[Any] = []
    while True:
        origin = typing.get_origin(annotation)
        if origin is typing.Annotated:
            metadata += [
                m for item in annotation.__metadata__ for m in getattr(item, "metadata", [item])
            ]
            annotation = typing.get_args(annotation)[0]
        elif origin in (typing.Union, types.UnionType):
            args = [a for a in typing.get_args(annotation) if a is not type(None)]
            annotation = args[0]
        elif origin in (list, tuple, dict):
            annotation = typing.get_args(annotation)[-1 if origin is dict else 0]
        else:
            return annotation, metadata


def _field(model: type[BaseModel], key: Any) -> FieldInfo | None:
    for name, info in model.model_fields.items():
        if key in (name, info.alias):
            return info
    return None


def figure_range(model: type[BaseModel], loc: tuple[Any, ...]) -> FigureRange | None:
    """The range of the figure at a pydantic error's `loc` (None: no range declared there)."""
    current: Any = model
    info: FieldInfo | None = None
    metadata: list[Any] = []
    table = False  # the last key named a table of sections: the next is a name in it
    for key in loc:
        if isinstance(key, int) or table:
            table = False
            continue
        if not (isinstance(current, type) and issubclass(current, BaseModel)):
            return None
        info = _field(current, key)
        if info is None:
            return None
        table = typing.get_origin(info.annotation) is dict
        current, metadata = _inner(info.annotation)
    if info is None:
        return None
    return _constraints([*info.metadata, *metadata])


def figures(model: type[BaseModel], prefix: str = "") -> Iterator[tuple[str, type, FigureRange]]:
    """Every number a section (and the sections inside it) declares: (dotted key, int or
    float, its range; a range of None ends when nothing bounds it)."""
    for name, info in model.model_fields.items():
        inner, metadata = _inner(info.annotation)
        key = f"{prefix}{info.alias or name}"
        if isinstance(inner, type) and issubclass(inner, BaseModel):
            yield from figures(inner, f"{key}.")
        elif inner in (int, float):
            found = _constraints([*info.metadata, *metadata]) or FigureRange(None, None)
            yield key, inner, found
