"""Per-tick series an experiment derives from a run's log, written beside it in the run directory.

log.csv holds what the loop measured and sent, as it happened (and lock-step logs stay the
same byte for byte); what follows from it through a model is computed once the run has ended
(`Experiment.derived_series`, written by `hil run` after the run: hil/session/session.py) and
kept in a file of its own. One row per log row it covers: `tick` first (it joins with
log.csv's), `time_s` (the loop's time, as in log.csv), then the experiment's columns; numbers
as log.csv writes them (9 decimals, NaN as `nan`).

kinematics.csv (`KINEMATICS_FILE`), DYROS-JET's experiments (stand, push, the walks): what the
robot's own sensors say, through the controller's model of the legs, the same computation as
their metrics (hil/experiments/humanoid.py, walking_kinematics.py), per tick:

    zmp_x_m, zmp_y_m                  the ZMP measured by the feet's force/torque sensors
                                      (NaN where the feet carry nothing)
    desired_zmp_x_m, desired_zmp_y_m  the ZMP the experiment wants: the posture's CoM on the
                                      ground (stand, push), the walking pattern's ZMP (walks)
    com_x_m, com_y_m, com_z_m         the centre of mass at the measured link angles
    pelvis_tilt_rad                   the pelvis's tilt from upright
    support_margin_m                  the measured ZMP's distance inside the support polygon
                                      (negative: outside): both soles' extent (stand, push),
                                      the soles in contact (walks)
    left_foot_vertical_n, right_foot_vertical_n   each foot's vertical force [N]

Positions in the ground frame the metrics use: the left sole's centre at the origin (stand,
push), the plan's frame, the middle of the soles at the start (walks); x forward, y left, z up.
The walks' rows start at the experiment's start (after any re-homing), the others' at tick 0.
"""

from __future__ import annotations

import csv
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hil.output.runlog import format_column, read_log

KINEMATICS_FILE = "kinematics.csv"
KINEMATICS_COLUMNS = (
    "tick",
    "time_s",
    "zmp_x_m",
    "zmp_y_m",
    "desired_zmp_x_m",
    "desired_zmp_y_m",
    "com_x_m",
    "com_y_m",
    "com_z_m",
    "pelvis_tilt_rad",
    "support_margin_m",
    "left_foot_vertical_n",
    "right_foot_vertical_n",
)


@dataclass(frozen=True)
class DerivedSeries:
    """Columns of one length, written as `file_name` in the run directory (module docstring)."""

    file_name: str
    columns: dict[str, np.ndarray]

    def __post_init__(self) -> None:
        names = list(self.columns)
        if names[:2] != ["tick", "time_s"]:
            raise ValueError(f"{self.file_name}: the first columns must be tick, time_s: {names}")
        shapes = {name: np.shape(values) for name, values in self.columns.items()}
        if len(set(shapes.values())) != 1 or len(shapes["tick"]) != 1:
            raise ValueError(f"{self.file_name}: columns must be 1-D of one length: {shapes}")


def kinematics_series(
    tick: np.ndarray,
    time_s: np.ndarray,
    zmp_m: np.ndarray,
    desired_zmp_m: np.ndarray,
    com_m: np.ndarray,
    tilt_rad: np.ndarray,
    margin_m: np.ndarray,
    vertical_n: np.ndarray,
) -> DerivedSeries:
    """kinematics.csv from per-tick arrays: zmp_m (n, 2), desired_zmp_m (n, 2) or (2,) for
    all ticks, com_m (n, 3), tilt_rad and margin_m (n,), vertical_n (n, 2) left, right."""
    n = len(tick)
    desired = np.broadcast_to(np.asarray(desired_zmp_m, dtype=float), (n, 2))
    values = (
        np.asarray(tick).astype(np.int64),
        time_s,
        zmp_m[:, 0],
        zmp_m[:, 1],
        desired[:, 0],
        desired[:, 1],
        com_m[:, 0],
        com_m[:, 1],
        com_m[:, 2],
        tilt_rad,
        margin_m,
        vertical_n[:, 0],
        vertical_n[:, 1],
    )
    return DerivedSeries(KINEMATICS_FILE, dict(zip(KINEMATICS_COLUMNS, values, strict=True)))


def write_series(out_dir: Path, series: DerivedSeries) -> Path:
    """`series` as CSV in `out_dir`, whole or not at all (a temporary file, then renamed)."""
    path = Path(out_dir) / series.file_name
    tmp = path.with_name(path.name + ".tmp")
    cells = [format_column(np.asarray(values)) for values in series.columns.values()]
    try:
        with open(tmp, "w", newline="") as f:
            writer = csv.writer(f, lineterminator="\n")
            writer.writerow(series.columns)
            writer.writerows(zip(*cells, strict=True))
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def read_series(path: Path) -> dict[str, np.ndarray]:
    """A derived series' columns as floats (`tick` as integers)."""
    columns = read_log(Path(path))
    if "tick" in columns:
        columns["tick"] = columns["tick"].astype(np.int64)
    return columns
