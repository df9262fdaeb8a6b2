"""`hil export ros2 RUN_DIR`: a finished run directory as a ROS 2 bag (hil/output/ros2_bag.py),
the same messages a run writes with `hil run --ros2`."""

from __future__ import annotations

from pathlib import Path

from hil.output.robot_description import robot_of_run
from hil.output.robot_frames import BaseTruth
from hil.output.ros2_bag import ROS2_BAG_NAME, Ros2Bag
from hil.output.run_samples import run_joint_names, samples_of_run, sensor_columns
from hil.output.rundir import load_run
from hil.output.tick_sample import VIEW_COLUMNS


def export_ros2(run_dir: Path, out: Path | None = None) -> Path:
    """The bag of a finished run directory (default RUN_DIR/run.ros2.mcap); returns its path."""
    run = load_run(run_dir)
    path = Path(out) if out is not None else run.out_dir / ROS2_BAG_NAME
    robot = robot_of_run(run.meta, run_joint_names(run), sensor_columns(run))
    bag = Ros2Bag(path, robot, run.meta, BaseTruth.of_run(run.out_dir))
    try:
        records = sorted(run.events, key=lambda e: float(e.get("time_s") or 0.0))
        pending = iter(records)
        event = next(pending, None)
        last_s = 0.0
        for sample in samples_of_run(run, VIEW_COLUMNS):
            while event is not None and float(event.get("time_s") or 0.0) <= sample.time_s:
                bag.event(event)
                event = next(pending, None)
            bag.tick(sample)
            last_s = sample.time_s
        while event is not None:
            bag.event(event)
            last_s = max(last_s, float(event.get("time_s") or 0.0))
            event = next(pending, None)
        if run.summary:
            bag.summary(run.summary, last_s)
    finally:
        bag.close()
    return path
