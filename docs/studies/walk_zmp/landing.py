"""Around a touchdown: the feet's measured normal forces against the plan's split (where the
planned ZMP lies between the feet, 0 left .. 1 right), the measured and planned CoM, and the
gravity compensator's offsets ug on the hip and ankle rolls (from the log).

    python docs/studies/walk_zmp/landing.py RUN_DIR FROM_S TO_S [STEP_S]
"""

import sys
from pathlib import Path

import numpy as np

from common import experiment_of, load
from hil.experiments.walking import PlannedTables
from hil.output.rundir import load_run

run, a, b = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
step = float(sys.argv[4]) if len(sys.argv) > 4 else 0.025
d, pat = load(run), experiment_of(run).pattern
log = load_run(Path(run))
log_t = log.time_s - log.experiment_start_s
split = PlannedTables.of(pat).split
rolls = ("L_HipRoll", "L_AnkleRoll", "R_HipRoll", "R_AnkleRoll")
for tt in np.arange(a, b, step):
    k, j = np.searchsorted(d["t"], tt), np.searchsorted(log_t, tt)
    left, right = d["vert"][k]
    ug = " ".join(f"{r} {1e3 * log.signal('ug_rad', r)[j]:+6.1f}" for r in rolls)
    kind = pat.timeline.phase(int(d["ticks"][k])).kind.value[:6]
    print(
        f"{d['t'][k]:5.2f} {kind} ZMP y {d['zmp'][k, 1]:+.3f} ({d['dzmp'][k, 1]:+.3f}) | Fz L {left:4.0f} R {right:4.0f}"
        f" share R {right / max(left + right, 1):.2f} plan {split[d['ticks'][k]]:.2f} | CoM y {d['com'][k, 1]:+.3f}"
        f" ({d['plancom'][k, 1]:+.3f}) | ug [mrad] {ug}"
    )
