import sys, numpy as np, json
from hil.output.rundir import load_run

run = load_run(sys.argv[1])
names = [c[len("link_angle_rad[") : -1] for c in run.columns if c.startswith("link_angle_rad[")]
links = np.column_stack(run.per_joint("link_angle_rad"))
mot = np.column_stack(run.per_joint("motor_angle_rad"))
cur = np.column_stack(run.per_joint("motor_current_a"))
sel = run.time_s > run.time_s[-1] - 1.0
for j, n in enumerate(names):
    print(
        f"{n:14s} link std {links[sel, j].std():.4f} motor std {mot[sel, j].std():.4f} cur max {np.abs(cur[sel, j]).max():.2f}"
    )
print(open(sys.argv[1] + "/summary.json").read()[:1500] if len(sys.argv) > 1 else "")
