"""What a sweep's numbers must be before anything is planned: whole counts, ranges that are
ranges (finite, low below high, a logarithmic one above zero)."""

from __future__ import annotations

import math
from typing import Any, Protocol


class SpecError(ValueError):
    """The sweep specification is malformed (the message names the key)."""


class Range(Protocol):
    name: str
    values: tuple[Any, ...]
    low: float | None
    high: float | None
    points: int | None
    log: bool


def whole_number(value: Any, what: str, minimum: int) -> int:
    """A TOML integer >= minimum (1e12 is a float: refused, not rounded)."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise SpecError(f"{what} must be a whole number, got {value!r}")
    if value < minimum:
        raise SpecError(f"{what} must be >= {minimum}, got {value}")
    return value


def check_range(parameter: Range) -> None:
    """A parameter's points or range, judged alone (after `relative` is made absolute too)."""
    where = f"parameter {parameter.name!r}"
    if parameter.points is not None:
        whole_number(parameter.points, f"{where}: points", 1)
    for key in ("low", "high"):
        value = getattr(parameter, key)
        if value is not None and not math.isfinite(value):
            raise SpecError(f"{where}: {key} must be finite, got {value}")
    low, high = parameter.low, parameter.high
    if low is not None and high is not None:
        if not low < high:
            raise SpecError(f"{where}: low ({low:g}) must be below high ({high:g})")
        if parameter.log and low <= 0:
            raise SpecError(
                f"{where}: a logarithmic range must lie above 0, got {low:g} .. {high:g}"
            )
