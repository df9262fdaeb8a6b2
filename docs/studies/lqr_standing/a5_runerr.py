import sys
from common import *
from hil.output.rundir import load_run

np.set_printoptions(precision=4, suppress=True, linewidth=180)
run = load_run(sys.argv[1])
links = np.column_stack(run.per_joint("link_angle_rad"))
ref = np.column_stack(run.per_joint("reference_rad"))
goal = np.column_stack(run.per_joint("goal_rad"))
for t in [float(x) for x in sys.argv[2:]]:
    k = int(np.searchsorted(run.time_s, t))
    S = sm(posture=links[k])
    w, V = np.linalg.eigh(S)
    Vr = V[:, w > 1e-9 * w.max()]
    Vc = V[:, w <= 1e-9 * w.max()]
    e = links[k] - ref[k]
    ec = Vc @ Vc.T @ e
    print(
        f"t={run.time_s[k]:.2f} |e|={np.linalg.norm(e) * 1e3:.2f} mrad, constrained part |Pc e|={np.linalg.norm(ec) * 1e3:.2f} mrad"
    )
    print("   e  [mrad]", e * 1e3)
    print("   Pc e     ", ec * 1e3)
