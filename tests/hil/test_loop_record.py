"""The loop writes a tick's rows during the next tick (while the bus answers travel): each row
still holds its own tick's sample and controller terms, and the last tick's row is written too."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

import hil.loop.run_record
from drivers.joint_bus import JointSample
from hil.config import load_config
from hil.experiments import IMPACT
from hil.wiring.in_process import InProcessJointBus, in_process_bus
from tests.support.rig import assert_log_complete, run_in_process

CONFIG = load_config()


class _RecordingBus(InProcessJointBus):
    """The in-process bus, keeping every sample it returned, in order."""

    samples: list[JointSample]

    def read(self) -> JointSample:
        sample = super().read()
        self.samples.append(sample)
        return sample


def test_each_row_holds_its_own_ticks_values(tmp_path: Path, monkeypatch) -> None:
    bus = in_process_bus(CONFIG, IMPACT)
    bus.__class__ = _RecordingBus
    bus.samples = []
    d_hats: dict[int, float] = {}
    real_keep = hil.loop.run_record.RunRecord.keep

    def keep(self, tick, sample, reference, goal, phase, state, terms, timing):
        if terms is not None:
            d_hats[tick.index] = float(terms["d_hat_rad"][0])
        real_keep(self, tick, sample, reference, goal, phase, state, terms, timing)

    monkeypatch.setattr(hil.loop.run_record.RunRecord, "keep", keep)
    result, run = run_in_process(CONFIG, IMPACT, "gc+lqr+dob", tmp_path, duration_s=1.5, bus=bus)
    assert result.ok
    assert_log_complete(run)
    with open(run.dir / "log.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    # the start gate reads once more on tick 0: the loop's own reads are the last len(rows)
    samples = bus.samples[-len(rows) :]
    motor = np.array([float(r["motor_angle_rad"]) for r in rows])
    np.testing.assert_allclose(motor, [s.motor_angle_rad[0] for s in samples], rtol=0, atol=1e-9)
    assert len(set(np.round(motor, 6))) > 50  # the link moved: a shifted row would show
    logged = {int(r["tick"]): float(r["d_hat_rad"]) for r in rows}
    assert len(d_hats) > 100 and len({round(v, 9) for v in d_hats.values()}) > 50
    for tick, value in d_hats.items():
        assert abs(logged[tick] - value) <= 1e-9 * max(1.0, abs(value)), tick
    with open(run.dir / "timing.csv", newline="") as f:
        assert len(list(csv.DictReader(f))) == len(rows)
