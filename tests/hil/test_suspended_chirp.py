"""The legs' identification excitation (hil/experiments/suspended.py): one joint of each leg
swept at a time within its rate, amplitude and the joints' limits; the held-out windows where
the down-sweeps are; the robot hung through the emulated buses, its feet off the floor."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hil.config import load_config
from hil.experiments import SUSPENDED_CHIRP
from hil.experiments.suspended import JOINTS_PER_LEG, LegChirp, SuspendedChirpExperiment
from hil.robots import get_experiment
from hil.vocabulary import Robot

PERIOD_S = 0.005


def test_each_window_sweeps_one_joint_of_each_leg() -> None:
    table = SUSPENDED_CHIRP.goal_offsets(PERIOD_S, 100_000, 12)
    window = int(round(SUSPENDED_CHIRP.window_s / PERIOD_S))
    assert SUSPENDED_CHIRP.duration_s == pytest.approx(6 * SUSPENDED_CHIRP.window_s)
    for w in range(JOINTS_PER_LEG):
        rows = table[w * window : (w + 1) * window]
        moving = np.flatnonzero(np.abs(rows).max(axis=0) > 0)
        assert list(moving) == [w, w + JOINTS_PER_LEG]  # the left and right joint w alone
        np.testing.assert_array_equal(rows[:, w], rows[:, w + JOINTS_PER_LEG])
        chirp = SUSPENDED_CHIRP.chirps[w]
        assert np.abs(rows).max() <= chirp.amplitude_rad + 1e-12
        rate = np.abs(np.diff(rows[:, w], prepend=0.0)).max() / PERIOD_S
        assert rate <= chirp.max_goal_rate_rad_s + 1e-9
    assert not table[6 * window :].any()  # nothing after the last window


def test_the_swing_stays_within_every_joints_limits() -> None:
    config = load_config(robot=Robot.DYROS_JET)
    low, high = SUSPENDED_CHIRP.reference_range(12)
    for joint, lo, hi in zip(config.joints, low, high, strict=True):
        assert joint.min_angle_rad < lo < hi < joint.max_angle_rad, joint.name


def test_the_held_out_ticks_are_each_windows_down_sweep_and_last_hold() -> None:
    ticks = int(round(SUSPENDED_CHIRP.duration_s / PERIOD_S))
    mask = SUSPENDED_CHIRP.held_out_mask(PERIOD_S, ticks)
    window = int(round(SUSPENDED_CHIRP.window_s / PERIOD_S))
    e = SUSPENDED_CHIRP
    held_s = e.validation_sweep_s + e.settle_s  # the down-sweep, then the last hold
    assert mask.sum() == pytest.approx(6 * held_s / PERIOD_S, abs=6)
    for w in range(JOINTS_PER_LEG):
        own = mask[w * window : (w + 1) * window]
        first = int(np.argmax(own))
        assert first == pytest.approx((e.settle_s + e.fit_sweep_s) / PERIOD_S, abs=1)
        assert own[first:].all() and not own[:first].any()


def test_it_is_dyros_jets_and_hangs_the_robot() -> None:
    assert get_experiment("suspended-chirp") is SUSPENDED_CHIRP
    assert SUSPENDED_CHIRP.world.suspended and SUSPENDED_CHIRP.open_loop


def test_a_chirp_the_excitation_cannot_keep_is_refused() -> None:
    too_fast = (LegChirp(0.1, 0.3, 60.0, 1.0),) * JOINTS_PER_LEG  # above Nyquist / 4
    with pytest.raises(ValueError, match="Nyquist"):
        SuspendedChirpExperiment("x", "x", posture_rad=SUSPENDED_CHIRP.posture_rad,
                                 chirps=too_fast)  # fmt: skip
    with pytest.raises(ValueError, match="12 angles"):
        SuspendedChirpExperiment("x", "x", posture_rad=(0.0,) * 6)


def test_hung_through_the_emulated_buses(tmp_path: Path) -> None:
    """`hil run suspended-chirp` on the emulated legs (the real path: its own emulator process,
    the unmodified SDKs): the robot hangs at the pelvis the whole run, the feet carry nothing,
    the excitation runs unchanged."""
    done = subprocess.run(
        [sys.executable, "-m", "hil", "run", "suspended-chirp", "--controller", "pid",
         "--duration", "4", "--out", str(tmp_path), "--no-plots", "--no-mcap", "--json"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    result = json.loads(done.stdout.strip().splitlines()[-1])
    out = Path(result["out_dir"])
    with (out / "emulator_truth.csv").open() as f:
        heights = [float(row["base_z_m"]) for row in csv.DictReader(f)]
    assert heights and max(heights) - min(heights) < 1e-9  # fixed in the world
    assert heights[0] > 1.0
    with (out / "log.csv").open() as f:
        rows = list(csv.DictReader(f))
    normal = [abs(float(r["left_foot_fz_n"])) + abs(float(r["right_foot_fz_n"])) for r in rows]
    assert max(normal) < 5.0  # nothing under the feet (the sensors' noise and offsets)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["termination"] == "completed"
    assert summary["metrics"]["excitation_coverage"] == 1.0
