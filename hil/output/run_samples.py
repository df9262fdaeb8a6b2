"""A finished run directory as `TickSample`s (hil/output/tick_sample.py), for the views made
after the run (`hil export ros2`, `hil render`)."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from hil.output.rundir import RunData
from hil.output.tick_sample import TickSample


def sensor_columns(run: RunData) -> tuple[str, ...]:
    """A log's named sensor columns: those between time_s and supervisor_state."""
    names = list(run.columns)
    return tuple(names[names.index("time_s") + 1 : names.index("supervisor_state")])


def samples_of_run(run: RunData, per_joint: tuple[str, ...]) -> Iterator[TickSample]:
    """Every row of a finished run's log, the per-joint columns `per_joint` only."""
    joints = {c: np.array(run.per_joint(c)).T for c in per_joint if _has(run, c)}
    sensors = sensor_columns(run)
    ticks, times = run.columns["tick"], run.time_s
    for i in range(len(times)):
        yield TickSample(
            int(ticks[i]),
            float(times[i]),
            {c: values[i] for c, values in joints.items()},
            {c: float(run.columns[c][i]) for c in sensors},
        )


def _has(run: RunData, column: str) -> bool:
    try:
        run.signal(column, run.joint_names[0])
    except KeyError:
        return False
    return True


def run_joint_names(run: RunData) -> tuple[str, ...]:
    """The log's joint names; a single-joint log's from meta.json (its columns have none)."""
    if run.joint_names != ("",):
        return run.joint_names
    joints = (run.meta.get("config") or {}).get("joint") or [{}]
    return (str(joints[0].get("name") or "joint"),)
