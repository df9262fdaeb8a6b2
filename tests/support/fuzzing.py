"""The fuzz tests' shared settings: case counts scale with FUZZ_SCALE (environment, default 1),
no per-example deadline (a loaded machine), and the health checks a byte-level fuzzer trips on
purpose (large inputs, slow generation) turned off."""

from __future__ import annotations

import os

from hypothesis import HealthCheck, settings

FUZZ_SCALE = max(1, int(os.environ.get("FUZZ_SCALE", "1")))


def examples(count: int) -> settings:
    """Hypothesis settings for `count` x FUZZ_SCALE cases."""
    return settings(
        max_examples=count * FUZZ_SCALE,
        deadline=None,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
    )
