import sys, numpy as np
from hil.output.rundir import load_run

run = load_run(sys.argv[1])
j = sys.argv[2]
a = int(sys.argv[3])
b = int(sys.argv[4])
st = int(sys.argv[5]) if len(sys.argv) > 5 else 1
c = run.columns
keys = [
    "reference_rad",
    "goal_rad",
    "motor_angle_rad",
    "link_angle_rad",
    "uc_rad",
    "d_hat_rad",
    "ug_rad",
    "motor_current_a",
]
print("tick time phase sup", " ".join(k.split("_")[0] for k in keys), "LFz RFz")
for i in range(a, min(b, len(run.time_s)), st):
    print(
        i,
        round(run.time_s[i], 3),
        c["phase"][i],
        c["supervisor_state"][i],
        " ".join(f"{float(c[f'{k}[{j}]'][i]):+.4f}" for k in keys),
        f"{c['left_foot_fz_n'][i]:.0f} {c['right_foot_fz_n'][i]:.0f}",
    )
