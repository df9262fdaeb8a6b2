"""Mid single support: which joints' link errors (link - plan) move the CoM, one joint at a
time through the URDF model with the stance sole flat (the CoM at the plan's angles with that
one joint at its measured angle, minus the CoM at the plan's angles).

    python docs/studies/walk_zmp/joints.py RUN_DIR
"""

import sys

import numpy as np

from common import experiment_of, load
from controller.humanoid import LEG_JOINT_NAMES
from hil.experiments.legs import leg_model, placed_configuration

run = sys.argv[1]
d, pat, model = load(run), experiment_of(run).pattern, leg_model()
t = d["t"]
for s in pat.timeline.segments:
    if s.kind.value != "single_support":
        continue
    a, b = s.start_tick * pat.dt_s, s.end_tick * pat.dt_s
    rows = np.flatnonzero((t >= a + 0.3 * (b - a)) & (t < b - 0.3 * (b - a)))
    if rows.size == 0 or not np.isfinite(d["links"][rows[rows.size // 2]]).all():
        continue
    k = rows[rows.size // 2]
    anchor, tick = int(d["anchors"][k]), int(d["ticks"][k])

    def com(angles):
        return model.centre_of_mass(placed_configuration(model, angles, anchor, pat, tick))

    ref, links = d["ref"][k], d["links"][k]
    base = com(ref)
    whole = com(links) - base
    print(
        f"single support {a:.2f}-{b:.2f} s, stance {'LR'[anchor]}: CoM (links) - CoM (plan) y {1e3 * whole[1]:+.1f} mm, x {1e3 * whole[0]:+.1f} mm"
    )
    for j, name in enumerate(LEG_JOINT_NAMES):
        angles = ref.copy()
        angles[j] = links[j]
        dc = com(angles) - base
        if abs(dc[1]) > 1e-3 or abs(dc[0]) > 2e-3:
            print(
                f"    {name:13s} link - plan {1e3 * (links[j] - ref[j]):+6.1f} mrad -> CoM y {1e3 * dc[1]:+6.1f} mm, x {1e3 * dc[0]:+6.1f} mm"
            )
