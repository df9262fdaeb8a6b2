import sys, numpy as np
from hil.output.rundir import load_run

run = load_run(sys.argv[1])
t0, t1 = float(sys.argv[2]), float(sys.argv[3])
names = [c[len("link_angle_rad[") : -1] for c in run.columns if c.startswith("link_angle_rad[")]
links = np.column_stack(run.per_joint("link_angle_rad"))
goal = np.column_stack(run.per_joint("goal_rad"))
ref = np.column_stack(run.per_joint("reference_rad"))
sel = (run.time_s >= t0) & (run.time_s < t1)
dt = 0.005
for j, n in enumerate(names):
    for tag, sig in (("err", links[sel, j] - ref[sel, j]), ("goal", goal[sel, j])):
        x = sig - np.polyval(np.polyfit(run.time_s[sel], sig, 1), run.time_s[sel])
        X = np.abs(np.fft.rfft(x * np.hanning(x.size)))
        f = np.fft.rfftfreq(x.size, dt)
        k = 1 + np.argmax(X[1:])
        print(
            f"{n:13s} {tag:4s} pk-pk {np.ptp(x) * 1e3:7.2f} mrad  peak {f[k]:6.2f} Hz  (Nyquist share {X[-3:].sum() / X.sum():.2f})"
        )
lf, rf = run.columns["left_foot_fz_n"][sel], run.columns["right_foot_fz_n"][sel]
for tag, x in (("LFz", lf), ("LFz-RFz", lf - rf)):
    x = x - x.mean()
    X = np.abs(np.fft.rfft(x * np.hanning(x.size)))
    f = np.fft.rfftfreq(x.size, dt)
    k = 1 + np.argmax(X[1:])
    print(tag, "peak", round(f[k], 2), "Hz, pk-pk", round(np.ptp(x), 1))
