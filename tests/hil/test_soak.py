"""The soak's short version: every kind of fault once (in process, lock-step), each reaction
within its documented bound, no log row lost, every exit state as reported. The long one is
`hil bench soak --cycles 100000` (its figures go in the closing notes)."""

from __future__ import annotations

import pytest

from hil.bench.soak import KINDS, run_soak
from hil.config import load_config

pytestmark = pytest.mark.slow


def test_every_fault_kind_once_reacts_within_bound_and_loses_no_row() -> None:
    # a run takes ~480 ticks: enough ticks for one run of each kind
    report = run_soak(load_config(), ticks=len(KINDS) * 400, seed=1)
    injected = {name: f["injected"] for name, f in report["kinds"].items()}
    assert all(count >= 1 for count in injected.values()), injected
    assert report["all_within_bound"], report["kinds"]
    assert report["rows_lost"] == 0
