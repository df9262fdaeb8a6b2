"""NaN and infinity are written as JSON null by the run log (meta.json, events.jsonl,
summary.json, run.mcap's metadata and messages) and by `add_to_summary`."""

from __future__ import annotations

import math
from pathlib import Path

from mcap.reader import make_reader

from hil.output.rundir import add_to_summary
from hil.output.runlog import RunLog
from hil.output.strict_json import dumps, plain, strict_loads


def test_plain_data_has_no_nan_and_keeps_everything_else() -> None:
    import numpy as np

    data = {"a": math.nan, "b": [math.inf, -math.inf, 1.5], 3: np.float64("nan"), "c": True,
            "d": np.arange(2), "e": None, "f": "NaN is a word here"}  # fmt: skip
    assert plain(data) == {"a": None, "b": [None, None, 1.5], "3": None, "c": True,
                           "d": [0, 1], "e": None, "f": "NaN is a word here"}  # fmt: skip
    assert strict_loads(dumps(data))["f"] == "NaN is a word here"


def test_the_run_log_writes_null_for_nan_everywhere(tmp_path: Path) -> None:
    meta = {"seed": 0, "offset": math.nan, "nested": {"limit": math.inf}}
    with RunLog(tmp_path, ["j"], meta, mcap=True) as log:
        log.event(0.1, "note", "a figure was not measured", value=math.nan)
        log.write_summary({"metrics": {"first_peak_rad": math.nan, "n": -math.inf}})
    add_to_summary(tmp_path, "emulator_fault_counts", {"rate": math.nan})
    assert strict_loads((tmp_path / "meta.json").read_text())["offset"] is None
    event = strict_loads((tmp_path / "events.jsonl").read_text().splitlines()[0])
    assert event["value"] is None
    summary = strict_loads((tmp_path / "summary.json").read_text())
    assert summary["metrics"] == {"first_peak_rad": None, "n": None}
    assert summary["emulator_fault_counts"] == {"rate": None}
    with open(tmp_path / "run.mcap", "rb") as f:
        reader = make_reader(f)
        for _schema, _channel, message in reader.iter_messages():
            strict_loads(message.data.decode())
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
    assert strict_loads(metadata["run_meta"]["offset"]) is None
    assert strict_loads(metadata["run_meta"]["nested"]) == {"limit": None}
    assert strict_loads(metadata["run_summary"]["metrics"])["first_peak_rad"] is None
