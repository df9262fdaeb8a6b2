"""Where the walk's ZMP error is: its rms over the single supports, the double supports' moving
ZMP (the lab's 0.1 s moves) and their held ZMP (between the feet), and each part's share of the
sum of squares (the walk: first double support to the end of the last).

    python docs/studies/walk_zmp/by_phase.py RUN_DIR [RUN_DIR ...]
"""

import sys

import numpy as np

from common import experiment_of, load

for run in sys.argv[1:]:
    d, pat = load(run), experiment_of(run).pattern
    t, e = d["t"], np.linalg.norm(d["zmp"] - d["dzmp"], axis=1)
    start = pat.timeline.segments[1].start_tick * pat.dt_s
    end = pat.timeline.segments[-1].start_tick * pat.dt_s
    walk = (t >= start) & (t < end) & np.isfinite(e)
    kinds = np.array([pat.timeline.phase(int(k)).kind.value for k in d["ticks"]])
    moving = np.abs(np.gradient(d["dzmp"][:, 1])) > 1e-6
    total = np.sum(e[walk] ** 2)
    parts = []
    for name, m in (
        ("single", kinds == "single_support"),
        ("double, ZMP moving", (kinds == "double_support") & moving),
        ("double, ZMP held", (kinds == "double_support") & ~moving),
    ):
        m = m & walk
        parts.append(
            f"{name}: {m.sum() * 0.005:.1f} s, rms {1e3 * np.sqrt(np.mean(e[m] ** 2)):.0f} mm ({100 * np.sum(e[m] ** 2) / total:.0f} %)"
        )
    print(f"{run}: rms {1e3 * np.sqrt(np.mean(e[walk] ** 2)):.1f} mm | " + " | ".join(parts))
