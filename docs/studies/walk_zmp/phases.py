"""Per walking segment (middle 60 %): measured ZMP against its reference, the CoM from the
encoders against the plan's, its acceleration, and the cart-table's ZMP of the measured CoM
(c - z/g c''), which must equal the measured ZMP if the measurement is consistent.

    python docs/studies/walk_zmp/phases.py RUN_DIR
"""

import sys

import numpy as np
from scipy.ndimage import uniform_filter1d

from common import experiment_of, load

run = sys.argv[1]
d, pat = load(run), experiment_of(run).pattern
t, com = d["t"], d["com"]
acc = uniform_filter1d(np.gradient(np.gradient(com[:, :2], t, axis=0), t, axis=0), 9, axis=0)
cart = com[:, :2] - com[:, 2:3] / 9.81 * acc
print(
    "segment            side  | ZMP y (ref)      | CoM y meas (plan) | a_y meas (plan) | c - z/g a"
)
for s in pat.timeline.segments[1:]:
    a, b = s.start_tick * pat.dt_s, s.end_tick * pat.dt_s
    m = (t >= a + 0.2 * (b - a)) & (t < b - 0.2 * (b - a))
    if not m.any():
        continue
    mean = lambda x: np.nanmean(x[m])  # noqa: E731
    side = s.landing_side.value if s.landing_side else "-"
    print(
        f"{s.kind.value:15s} {a:5.2f} {side:5s} | {mean(d['zmp'][:, 1]):+.3f} ({mean(d['dzmp'][:, 1]):+.3f})"
        f" | {mean(com[:, 1]):+.3f} ({mean(d['plancom'][:, 1]):+.3f})"
        f" | {mean(acc[:, 1]):+.2f} ({mean(d['planacc'][:, 1]):+.2f}) | {mean(cart[:, 1]):+.3f}"
    )
