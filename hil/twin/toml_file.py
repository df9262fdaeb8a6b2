"""The twin as a configuration file: the recorded configuration with the twin's [emulator],
every key written (a file `hil emulate --config` and `hil run --config ... --emulate` read as
they read any), headed by what was fitted from which runs and how well (TOML comments)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import tomli_w

from hil.config import Config, parse_config


def _without_nulls(value: Any) -> Any:
    """TOML has no null: a key whose value is None is left out (its default, the same value)."""
    if isinstance(value, dict):
        return {k: _without_nulls(v) for k, v in value.items() if v is not None}
    if isinstance(value, list):
        return [_without_nulls(v) for v in value]
    return value


def config_text(config: Config, header: Sequence[str] = ()) -> str:
    """The configuration as TOML (checked: it reads back as the same configuration)."""
    record = config.record()
    record.pop("source", None)
    body = tomli_w.dumps(_without_nulls(record))
    text = "".join(f"# {line}\n" if line else "#\n" for line in header) + "\n" + body
    if parse_config(text, "<twin>").record() | {"source": None} != record | {"source": None}:
        raise AssertionError("the twin's file does not read back as its configuration")
    return text


def write_config(config: Config, path: Path, header: Sequence[str] = ()) -> Path:
    path.write_text(config_text(config, header))
    return path
