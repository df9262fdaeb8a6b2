"""Every JSON document a run writes parses with a strict parser: a figure that could not be
measured is `null`, never the bare words NaN or Infinity (which JSON does not have).

The run: the impact with the link encoder dead from 0.5 s (its first peak cannot be measured),
through `hil run --json` on the embedded emulator, as a user runs it.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import re
from pathlib import Path

import pytest
from mcap.reader import make_reader

from hil.cli import main
from hil.output.strict_json import strict_loads


def _mcap_documents(path: Path) -> tuple[list[object], dict[str, dict[str, str]]]:
    with open(path, "rb") as f:
        reader = make_reader(f)
        messages = [
            strict_loads(m.data.decode())
            for _s, c, m in reader.iter_messages()
            if c.message_encoding == "json"  # (the 3D view's /tf is protobuf)
        ]
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
    return messages, metadata


@pytest.mark.timeout(120)
def test_a_dead_encoders_unmeasurable_figures_are_null_in_every_json_written(
    tmp_path: Path,
) -> None:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(
            ["run", "impact", "--inject", "dead_encoder@0.5", "--duration", "1.6", "--json",
             "--no-plots", "--out", str(tmp_path)]
        )  # fmt: skip
    assert code == 1  # the dead encoder stops the run (link_stale)
    (run_dir,) = tmp_path.iterdir()
    # the result's log line tells the run's length from the time it took ("(325 ticks, 0.6 s)"
    # read as a 0.6 s log)
    assert re.search(
        r"\(325 ticks = 1\.62 s of run time, in [\d.]+ s on the wall clock\)", out.getvalue()
    )
    line = strict_loads(out.getvalue().strip().splitlines()[-1])
    assert line["first_peak_rad"] is None
    summary = strict_loads((run_dir / "summary.json").read_text())
    assert summary["metrics"]["first_peak_rad"] is None
    strict_loads((run_dir / "meta.json").read_text())
    for text in (run_dir / "events.jsonl").read_text().splitlines():
        strict_loads(text)
    messages, metadata = _mcap_documents(run_dir / "run.mcap")
    assert messages
    for record in metadata.values():
        for value in record.values():
            strict_loads(value)
    assert strict_loads(metadata["run_summary"]["metrics"])["first_peak_rad"] is None


def test_the_strict_parser_of_these_tests_refuses_nan() -> None:
    with pytest.raises(ValueError):
        strict_loads(json.dumps({"x": math.nan}))
