"""The arm experiments' metrics (hil/experiments/arm.py) on a made-up log whose figures are
known by construction: a push's first peak and settling, a trajectory's tracking error."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hil.experiments.arm import (
    SETTLE_BAND_RAD,
    JointMove,
    PushExperiment,
    TrajectoryExperiment,
)
from hil.experiments.base import ToolPush, World
from hil.output.rundir import RunData

TIME = np.arange(0, 6.0, 0.005)
JOINTS = ("a", "b")


def run_of(reference: np.ndarray, link: np.ndarray) -> RunData:
    columns = {"time_s": TIME}
    for j, name in enumerate(JOINTS):
        columns[f"reference_rad[{name}]"] = reference[:, j]
        columns[f"link_angle_rad[{name}]"] = link[:, j]
        columns[f"motor_angle_rad[{name}]"] = link[:, j]
    return RunData(Path("."), columns, {}, {"experiment_start_s": 0.0}, (), JOINTS)


def test_a_push_s_first_peak_and_settling() -> None:
    push = PushExperiment(
        name="p", title="p", duration_s=6.0, start_rad=0.0,
        world=World(tool_pushes=(ToolPush(2.0, 0.2, (0.0, 0.0, -20.0)),)),
    )  # fmt: skip
    reference = np.zeros((TIME.size, 2))
    link = np.full((TIME.size, 2), 0.003)  # a static offset before the push: not the peak
    after = TIME >= 2.0
    # joint b: a decaying response 0.02 rad high, settling within the band 1.2 s after the
    # push's end (0.02 exp(-t / 0.3) < 1 mrad at t = 0.3 ln 20 = 0.899 s after 2.0 s)
    link[after, 1] += 0.02 * np.exp(-(TIME[after] - 2.0) / 0.3)
    metrics = push.metrics(run_of(reference, link))
    assert metrics["first_peak_rad"] == pytest.approx(0.02, rel=1e-6)
    expected = 0.3 * np.log(0.02 / SETTLE_BAND_RAD) - 0.2
    assert metrics["settling_s"] == pytest.approx(expected, abs=0.01)


def test_a_trajectory_s_tracking_error() -> None:
    trajectory = TrajectoryExperiment(
        name="t", title="t", duration_s=6.0, start_rad=(0.0, 0.0),
        moves=(JointMove(1.0, 2.0, (0.0, 0.0), (0.4, -0.2)),),
    )  # fmt: skip
    reference = np.array([trajectory.reference(t) for t in TIME])
    link = reference.copy()
    link[:, 0] -= 0.01  # joint a lags by 10 mrad throughout
    metrics = trajectory.metrics(run_of(reference, link))
    assert metrics["tracking_rms_rad"] == pytest.approx(0.01)
    assert metrics["tracking_peak_rad"] == pytest.approx(0.01)
