"""JSON as a strict parser reads it: NaN and infinity are `null`, wherever hil writes JSON.

Python's `json` writes NaN and infinity as the bare words `NaN` and `Infinity`, which JSON
(RFC 8259) does not have: a strict parser (JavaScript's `JSON.parse`, `jq`, Go, Rust's
serde_json) refuses the whole document. A figure that could not be measured (a dead encoder's
first peak, an empty statistic) is `null` instead. Every JSON document hil writes - meta.json,
summary.json, events.jsonl, the `--json` lines, run.mcap's metadata and messages, a sweep's
summary - goes through `dumps` (per-tick messages through the faster `channels.encode`).
"""

from __future__ import annotations

import json
import math
from typing import Any


def plain(value: Any) -> Any:
    """`value` as plain JSON data: non-finite floats -> None, numpy scalars and arrays -> Python
    numbers and lists, mapping keys -> text, anything else JSON has no type for -> its text."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if value is None or isinstance(value, str | bool | int):
        return value
    if isinstance(value, dict):
        return {str(key): plain(item) for key, item in value.items()}
    if isinstance(value, list | tuple | set | frozenset):
        return [plain(item) for item in value]
    if hasattr(value, "tolist"):  # numpy scalars and arrays
        return plain(value.tolist())
    return str(value)


def dumps(value: Any, **kwargs: Any) -> str:
    """json.dumps of `plain(value)`; a NaN that got through would raise, not be written."""
    return json.dumps(plain(value), allow_nan=False, **kwargs)


def strict_loads(text: str) -> Any:
    """json.loads that refuses NaN and infinity, as a strict parser does (for reading back and
    for the tests)."""

    def refuse(word: str) -> Any:
        raise ValueError(f"not JSON: {word}")

    return json.loads(text, parse_constant=refuse)
