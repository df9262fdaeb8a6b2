"""The run log as message channels: what run.mcap holds and what `hil run --live` serves.

Every channel is JSON with a JSON schema (message encoding "json", schema encoding
"jsonschema"), which Foxglove and PlotJuggler open without conversion. One message per tick on
each per-tick channel; NaN and infinity (a value not read this tick, a link never fresh) are
JSON null.

    /joints        per tick: tick, time_s, and per joint each PER_JOINT_COLUMNS entry as an
                   array in joint order (the names: the channel's metadata `joint_names` and
                   /run/meta), e.g. /joints.link_angle_rad[0]
    /loop          per tick: tick, time_s, the named sensors (contact_force_n), supervisor_state,
                   phase, skipped_ticks, slack_s, measured_period_s (the rest of a log.csv row)
    /timing        per tick: read_s, compute_s, write_s, log_s, cycle_s (timing.csv)
    /events        each supervisor event / bus note of events.jsonl (time_s, kind, message, ...)
    /run/meta      once, at the start: meta.json
    /run/summary   once, at the end: summary.json

Further channels derived from these (the robot in 3D: hil/output/robot_view.py) may be in
another encoding: a Channel names its message and schema encodings, and carries its schema's
bytes when it is not a JSON schema (Foxglove's protobuf schemas).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

from hil.output.strict_json import dumps

BOOL_COLUMNS = frozenset({"torque_enabled", "motor_valid", "link_valid"})
INTEGER_COLUMNS = frozenset({"actuator_fault"})
TIMING_FIELDS = ("read_s", "compute_s", "write_s", "log_s", "cycle_s")

JOINTS, LOOP, TIMING, EVENTS, META, SUMMARY = (
    "/joints",
    "/loop",
    "/timing",
    "/events",
    "/run/meta",
    "/run/summary",
)


class MessageSink(Protocol):
    """Where encoded messages go (the MCAP file, the live server)."""

    def add_channel(self, channel: Channel) -> None: ...

    def message(self, channel_id: int, log_time_ns: int, data: bytes) -> None: ...

    def close(self) -> None: ...


@dataclass(frozen=True)
class Channel:
    id: int
    topic: str
    schema_name: str
    schema: dict[str, Any]
    metadata: dict[str, str] = field(default_factory=dict)
    message_encoding: str = "json"
    schema_encoding: str = "jsonschema"
    schema_data: bytes | None = None  # the schema's bytes when it is not `schema` (JSON)

    @property
    def schema_bytes(self) -> bytes:
        if self.schema_data is not None:
            return self.schema_data
        return json.dumps(self.schema).encode()


def _number(nullable: bool = True) -> dict[str, Any]:
    return {"type": ["number", "null"]} if nullable else {"type": "number"}


def _object(title: str, properties: dict[str, Any], extra: bool = False) -> dict[str, Any]:
    return {
        "title": title,
        "type": "object",
        "properties": properties,
        "additionalProperties": extra,
    }


def _array_of(column: str) -> dict[str, Any]:
    if column in BOOL_COLUMNS:
        items: dict[str, Any] = {"type": "boolean"}
    elif column in INTEGER_COLUMNS:
        items = {"type": "integer"}
    else:
        items = _number()
    return {"type": "array", "items": items}


class ChannelSet:
    """The run log's channels for one run (see the module docstring)."""

    def __init__(
        self,
        joint_names: Sequence[str],
        per_joint_columns: Sequence[str],
        sensor_columns: Sequence[str],
    ) -> None:
        self.channels: list[Channel] = []
        tick = {"tick": {"type": "integer"}, "time_s": _number(False)}
        joints = {**tick, **{c: _array_of(c) for c in per_joint_columns}}
        names = {"joint_names": ",".join(joint_names)}
        self.joints = self.add(JOINTS, "hil.Joints", _object("hil.Joints", joints), names)
        loop = {
            **tick,
            **{name: _number() for name in sensor_columns},
            "supervisor_state": {"type": "string"},
            "phase": {"type": "string"},
            "skipped_ticks": {"type": "integer"},
            "slack_s": _number(),
            "measured_period_s": _number(),
        }
        self.loop = self.add(LOOP, "hil.Loop", _object("hil.Loop", loop))
        timing = {"tick": {"type": "integer"}, **{name: _number() for name in TIMING_FIELDS}}
        self.timing = self.add(TIMING, "hil.Timing", _object("hil.Timing", timing))
        text = {"type": "string"}
        event = {"time_s": _number(False), "kind": text, "message": text}
        self.events = self.add(EVENTS, "hil.Event", _object("hil.Event", event, extra=True))
        self.meta = self.add(META, "hil.RunMeta", _object("hil.RunMeta", {}, extra=True))
        self.summary = self.add(SUMMARY, "hil.RunSummary", _object("hil.RunSummary", {}, True))

    def add(
        self,
        topic: str,
        schema_name: str,
        schema: dict[str, Any],
        metadata: dict[str, str] | None = None,
        **encoding: Any,
    ) -> Channel:
        """A further channel (`encoding`: Channel's message_encoding, schema_encoding and
        schema_data, when not JSON)."""
        channel = Channel(
            len(self.channels), topic, schema_name, schema, metadata or {}, **encoding
        )
        self.channels.append(channel)
        return channel


def encode(message: dict[str, Any]) -> bytes:
    """JSON bytes with NaN and infinity as null (JSON has neither)."""
    text = json.dumps(message, separators=(",", ":"), default=_plain)
    if "NaN" in text or "Infinity" in text:
        text = text.replace("-Infinity", "null").replace("Infinity", "null")
        text = text.replace("NaN", "null")
    return text.encode()


def encode_document(document: dict[str, Any]) -> bytes:
    """A whole document (meta, summary, an event): NaN and infinity as null, done properly."""
    return dumps(document).encode()


def _plain(value: Any) -> Any:
    """numpy scalars and arrays, and anything else as its text."""
    if hasattr(value, "tolist"):
        return value.tolist()
    return str(value)
