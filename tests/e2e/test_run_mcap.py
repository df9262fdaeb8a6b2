"""run.mcap written by `hil run` (embedded emulator in a child process) reads back with the
`mcap` library's reader: every channel, every row of log.csv and timing.csv, every event, the
metadata and the summary - the same values as the CSV and JSON files."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import pytest
from mcap.reader import make_reader

from hil.output.runlog import PER_JOINT_COLUMNS
from tests.support.rig import hil_run

TOPICS = {"/joints", "/loop", "/timing", "/events", "/run/meta", "/run/summary"}
VIEW_TOPICS = {"/tf", "/tf_static", "/robot_description"}  # the robot in 3D (test_robot_view)


def _messages(path: Path) -> tuple[dict, dict[str, list[dict]], dict[str, dict[str, str]]]:
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None  # finished: index and statistics written
        channels = {c.topic: c for c in summary.channels.values()}
        schemas = {
            c.topic: (summary.schemas[c.schema_id], c.message_encoding) for c in channels.values()
        }
        by_topic: dict[str, list[dict]] = {topic: [] for topic in channels}
        for _schema, channel, message in reader.iter_messages(log_time_order=False):
            if channel.message_encoding == "json":
                by_topic[channel.topic].append(json.loads(message.data))
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
    return schemas, by_topic, metadata


def _same(csv_text: str, value: object) -> bool:
    """A CSV cell (9 decimals, 'nan', '1'/'0' for flags) against the message's value."""
    if value is None:
        return csv_text in ("nan", "inf", "-inf")
    if isinstance(value, bool):
        return csv_text == ("1" if value else "0")
    return math.isclose(float(csv_text), float(value), abs_tol=1e-9)


@pytest.mark.timeout(120)
def test_hil_run_writes_an_mcap_with_every_channel_and_row(tmp_path: Path) -> None:
    run = hil_run(tmp_path, "contact", "--controller", "gc+lqr+dob", "--duration", "1.0")
    assert run.exit_code == 0
    schemas, messages, metadata = _messages(run.dir / "run.mcap")
    assert set(schemas) == TOPICS | VIEW_TOPICS
    for schema, encoding in (schemas[topic] for topic in TOPICS):
        assert (schema.encoding, encoding) == ("jsonschema", "json")
        properties = json.loads(schema.data)["properties"]
        assert isinstance(properties, dict)
    rows = list(csv.DictReader((run.dir / "log.csv").open()))
    assert len(messages["/joints"]) == len(messages["/loop"]) == len(rows) > 200
    joint_properties = json.loads(schemas["/joints"][0].data)["properties"]
    for row, joints, loop in zip(rows, messages["/joints"], messages["/loop"], strict=True):
        assert set(joints) == set(joint_properties)
        assert joints["tick"] == int(row["tick"]) == loop["tick"]
        for column in PER_JOINT_COLUMNS:
            assert _same(row[column], joints[column][0]), (column, row[column], joints[column])
        for column in ("time_s", "contact_force_n", "skipped_ticks", "slack_s"):
            assert _same(row[column], loop[column]), column
        assert (loop["supervisor_state"], loop["phase"]) == (row["supervisor_state"], row["phase"])
    timing = list(csv.DictReader((run.dir / "timing.csv").open()))
    assert [m["tick"] for m in messages["/timing"]] == [int(r["tick"]) for r in timing]
    pairs = zip(timing, messages["/timing"], strict=True)
    # timing.csv holds 7 decimals
    assert all(math.isclose(float(r["log_s"]), m["log_s"], abs_tol=1e-7) for r, m in pairs)
    events = [json.loads(line) for line in (run.dir / "events.jsonl").read_text().splitlines()]
    assert [(e["kind"], e["message"]) for e in messages["/events"]] == [
        (e["kind"], e["message"]) for e in events
    ]
    meta = json.loads((run.dir / "meta.json").read_text())
    assert messages["/run/meta"] == [json.loads(json.dumps(meta))]
    summary = json.loads((run.dir / "summary.json").read_text())
    (mcap_summary,) = messages["/run/summary"]
    assert mcap_summary["termination"] == summary["termination"] == "completed"
    assert mcap_summary["metrics"].keys() == summary["metrics"].keys()
    assert json.loads(metadata["run_meta"]["experiment"]) == "contact"
    assert json.loads(metadata["run_summary"]["ticks"]) == summary["ticks"]
