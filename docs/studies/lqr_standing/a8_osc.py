import sys, numpy as np
from hil.output.rundir import load_run
from hil.experiments.humanoid import StandingKinematics

run = load_run(sys.argv[1])
t0, t1 = float(sys.argv[2]), float(sys.argv[3])
names = [c[len("link_angle_rad[") : -1] for c in run.columns if c.startswith("link_angle_rad[")]
links = np.column_stack(run.per_joint("link_angle_rad"))
goal = np.column_stack(run.per_joint("goal_rad"))
ref = np.column_stack(run.per_joint("reference_rad"))
sel = (run.time_s >= t0) & (run.time_s < t1)
t = run.time_s[sel]


def fit(x):
    """best single sinusoid (frequency scan 0.5-20 Hz) on detrended x: f, amplitude"""
    x = x - np.polyval(np.polyfit(t, x, 1), t)
    best = (0, 0)
    for f in np.arange(0.5, 20, 0.02):
        c, s = np.cos(2 * np.pi * f * t), np.sin(2 * np.pi * f * t)
        a = np.linalg.lstsq(np.column_stack([c, s]), x, rcond=None)[0]
        amp = np.hypot(*a)
        if amp > best[1]:
            best = (f, amp)
    return best


for j, n in enumerate(names):
    fe, ae = fit(links[sel, j])
    fg, ag = fit(goal[sel, j])
    print(
        f"{n:13s} link {fe:5.2f} Hz amp {ae * 1e3:6.2f} mrad | goal {fg:5.2f} Hz amp {ag * 1e3:6.2f} mrad"
    )
k = StandingKinematics.of(run)
for i, ax in enumerate("xy"):
    z = k.zmp_m[sel, i]
    ok = np.isfinite(z)
    f, a = fit(np.where(ok, z, np.nanmean(z)))
    print(
        f"ZMP {ax}: {f:.2f} Hz amp {a * 100:.2f} cm, range {np.nanmin(z):.3f}..{np.nanmax(z):.3f}"
    )
f, a = fit(run.columns["left_foot_fz_n"][sel] - run.columns["right_foot_fz_n"][sel])
print(f"LFz-RFz: {f:.2f} Hz amp {a:.0f} N")
f, a = fit(k.tilt_rad[sel])
print(f"tilt: {f:.2f} Hz amp {a * 1e3:.1f} mrad")
