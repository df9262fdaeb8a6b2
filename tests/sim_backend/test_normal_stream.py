"""`NormalStream` gives, draw for draw, what one `Generator.normal(0, rms)` call per draw gives:
the emulator's noise (servo currents, encoder counts, force/torque channels) keeps its seeded
values while it is drawn a block at a time."""

from __future__ import annotations

import numpy as np

from sim_backend.normal_stream import NormalStream


def test_draws_equal_one_normal_call_per_draw_across_blocks() -> None:
    stream = NormalStream(np.random.default_rng([3, 1000]))
    reference = np.random.default_rng([3, 1000])
    rng = np.random.default_rng(0)
    for _ in range(3000):  # crosses several block refills, with draws of 1, 2, 6 and 12
        count = int(rng.choice([1, 2, 6, 12]))
        rms = float(rng.uniform(0.001, 2.0))
        if count == 1:
            assert stream.next() * rms == float(reference.normal(0.0, rms))
        else:
            got = stream.take(count) * rms
            assert got.tolist() == reference.normal(0.0, rms, count).tolist()
