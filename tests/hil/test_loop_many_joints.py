"""The loop for n joints: six testbed joints (a leg's worth) on the in-process bus (one
Dynamixel chain, one CAN channel), every signal logged per joint, metrics and plots over all
joints. (`hil bench loop` runs 12 through the emulated buses.)"""

from __future__ import annotations

from pathlib import Path

from hil.bench.common import config_with_joints
from hil.config import load_config
from hil.experiments import IMPACT
from hil.experiments.impact import joint_impact_metrics
from hil.output import PER_JOINT_COLUMNS
from hil.output.plots import plot_run
from tests.support.rig import assert_log_complete, run_in_process


def test_six_joints_run_log_and_plot_joint_by_joint(tmp_path: Path) -> None:
    config = config_with_joints(load_config(), 6)
    # 1.6 s: the push at 1 s and the first peak's 0.5 s window after it (hil/experiments/impact.py)
    result, run = run_in_process(config, IMPACT, "gc+lqr+dob", tmp_path, duration_s=1.6)
    assert result.ok
    assert_log_complete(run)
    assert run.data.joint_names == config.joint_names
    for name in config.joint_names:
        for column in PER_JOINT_COLUMNS:
            assert f"{column}[{name}]" in run.columns
    # the push hits joint 0's load only: its link moves, the others hold
    push_s = IMPACT.world.pushes[0].start_s
    first_peaks = [
        joint_impact_metrics(
            run.data.time_s,
            run.data.signal("link_angle_rad", name),
            run.data.signal("reference_rad", name),
            push_s,
        )["first_peak_rad"]
        for name in config.joint_names
    ]
    assert first_peaks[0] > 10 * max(first_peaks[1:])
    assert result.metrics["first_peak_rad"] == first_peaks[0]  # the largest of any joint
    paths = plot_run(run.data, IMPACT.marks(run.data))
    assert [p.name for p in paths] == [f"plot-{name}.png" for name in config.joint_names]
