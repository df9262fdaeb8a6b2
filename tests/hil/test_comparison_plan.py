"""The testbed comparison's plan makes no run twice, whatever the configured reading of (25).

Before: with `[controller] composition = "accumulated-integral"` the long contact ran the DOB in
the configured reading and in "accumulated-integral" - the same run under two labels."""

from __future__ import annotations

import pytest

from controller import CompositionReading
from hil.robots.testbed.comparison import comparison_plan


@pytest.mark.parametrize("reading", list(CompositionReading))
def test_no_run_of_the_comparison_is_made_twice(reading: CompositionReading) -> None:
    plan = comparison_plan(reading)
    runs = [
        (
            experiment.name,
            choice.name,
            choice.kdist,
            choice.reading or reading,
            choice.gc_compliance,
        )
        for experiment, choice in plan
    ]
    assert len(runs) == len(set(runs)), runs
    long_contact = {r[3] for r in runs if r[0] == "contact-long"}
    assert len(long_contact) == 2 and CompositionReading.ACCUMULATED_INTEGRAL in long_contact
