"""The emulator's ground truth beside an emulated humanoid run (sim_backend/truth_log.py):
one row per tick, the plant's pelvis pose, and the exported bag's world -> base_link is that
truth (said so in the channel's metadata), not the leg odometry."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from hil.cli import main

pytest.importorskip("mcap_ros2", reason="the ros2 extra (mcap-ros2-support) is not installed")


def test_an_emulated_stand_leaves_its_truth_and_the_bag_publishes_it(tmp_path: Path) -> None:
    argv = ["run", "push", "--duration", "1.5", "--out", str(tmp_path), "--no-plots"]
    assert main(argv) == 0
    (run,) = tmp_path.iterdir()
    truth = np.genfromtxt(run / "emulator_truth.csv", delimiter=",", names=True)
    log = np.genfromtxt(run / "log.csv", delimiter=",", names=True, usecols=(0, 1))
    assert len(truth) == len(log)  # one SYNC per tick (no start-gate re-read)
    np.testing.assert_allclose(truth["time_s"], log["time_s"], atol=1e-9)
    assert np.ptp(truth["base_x_m"]) > 1e-3  # the push moved the pelvis
    quaternion = np.column_stack([truth[f"base_q{c}"] for c in "xyzw"])
    np.testing.assert_allclose(np.linalg.norm(quaternion, axis=1), 1.0, atol=1e-6)

    assert main(["export", "ros2", str(run)]) == 0
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    with AnyReader(
        [run / "run.ros2.mcap"], default_typestore=get_typestore(Stores.ROS2_JAZZY)
    ) as reader:
        (tf,) = [c for c in reader.connections if c.topic == "/tf"]
        bases = []
        for connection, _time, raw in reader.messages(connections=[tf]):
            message = reader.deserialize(raw, connection.msgtype)
            base = next(t for t in message.transforms if t.child_frame_id == "base_link")
            bases.append([base.transform.translation.x, base.transform.translation.y,
                          base.transform.translation.z])  # fmt: skip
    bases = np.array(bases)
    expected = np.column_stack([truth["base_x_m"], truth["base_y_m"], truth["base_z_m"]])
    np.testing.assert_allclose(bases, expected[: len(bases)], atol=1e-9)
    assert len(bases) >= len(expected) - 2
    from mcap.reader import make_reader

    with open(run / "run.ros2.mcap", "rb") as f:
        channels = make_reader(f).get_summary().channels.values()
    (tf_channel,) = [c for c in channels if c.topic == "/tf"]
    assert "emulator's ground truth" in json.dumps(tf_channel.metadata)


def test_a_planned_run_whose_directory_is_not_made_yet_starts_its_emulator(
    tmp_path: Path,
) -> None:
    """A comparison names its runs' directories and makes them as each run begins: the
    emulator, which opens its truth there first, must find it (before, every humanoid
    comparison run failed at start-up with FileNotFoundError)."""
    from hil.config import load_config
    from hil.robots import get_experiment
    from hil.session import Session, Setup
    from hil.vocabulary import ControllerChoice, ControllerKind

    config = load_config(robot="dyros-jet")
    session = Session(config, Setup.EMBEDDED, out_root=tmp_path, plots=False, quiet=True)
    out_dir = tmp_path / "comparison" / "stand-gc"
    result = session.run_one(
        get_experiment("stand"),
        ControllerChoice(ControllerKind.GC),
        duration_s=0.2,
        out_dir=out_dir,
        print_result=False,
    )
    assert result.termination.ran_its_course, result.ending
    assert (out_dir / "emulator_truth.csv").stat().st_size > 0
