import sys, numpy as np
from hil.output.rundir import load_run
from hil.experiments.humanoid import StandingKinematics, STAND

run = load_run(sys.argv[1])
k = StandingKinematics.of(run)
step = int(sys.argv[2]) if len(sys.argv) > 2 else 40
links = np.column_stack(run.per_joint("link_angle_rad"))
goal = np.column_stack(run.per_joint("goal_rad")) if "goal_rad" in str(run.columns.keys()) else None
print(list(run.columns.keys())[:40])
for i in range(0, len(run.time_s), step):
    print(
        round(run.time_s[i], 3),
        np.round(k.zmp_m[i], 3),
        round(k.vertical_n[i], 1),
        round(k.tilt_rad[i], 4),
        run.columns["phase"][i] if "phase" in run.columns else "",
        np.round(links[i, :6], 3),
    )
