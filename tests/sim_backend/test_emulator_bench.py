"""`sim_backend.bench`: the emulator's per-tick work and MuJoCo alone, on both robots.

No timing is asserted (the machine is shared): the bench must run the real paths (its tick is
answered by every device and node), and MuJoCo alone must step the plant's own model."""

from __future__ import annotations

import pytest

from hil.config import load_config
from hil.wiring.emulation import emulator_spec
from sim_backend.bench import EmulatorBench, interleaved, mujoco_plants


@pytest.mark.parametrize("robot", ["testbed", "dyros-jet"])
def test_the_bench_times_a_tick_advance_and_mujoco_alone(robot: str) -> None:
    bench = EmulatorBench(emulator_spec(load_config(robot=robot)))
    assert all(device.torque_enabled for device in bench.hardware.devices)
    plants = mujoco_plants(bench.hardware)
    assert len(plants) == (1 if robot == "dyros-jet" else len(bench.hardware.devices))
    time_before = bench.hardware.time_s
    figures = interleaved(bench, ticks=4, rounds=2)
    assert set(figures) == {"mujoco_alone", "advance", "tick", "in_process"}
    assert all(value > 0 for value in figures.values())
    # advance and tick moved the hardware by their ticks; MuJoCo alone stepped its own copy
    assert bench.hardware.time_s == pytest.approx(time_before + 16 * bench.spec.period_s)
    assert plants[0].data.time == pytest.approx(bench.hardware.time_s)
