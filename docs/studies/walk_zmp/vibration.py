"""The ZMP error's content above 2 Hz (a 2nd-order Butterworth high pass, zero phase) over the
walk, and the lateral error's spectral peak above 2 Hz (Welch): what the paper's LQR is said to
suppress ("the proposed LQR controller alone can suppress the small vibration", Sec. IV-C).

    python docs/studies/walk_zmp/vibration.py RUN_DIR [RUN_DIR ...]
"""

import sys

import numpy as np
from scipy.signal import butter, filtfilt, welch

from common import experiment_of, load

for run in sys.argv[1:]:
    d, pat = load(run), experiment_of(run).pattern
    t, e = d["t"], d["zmp"] - d["dzmp"]
    start = pat.timeline.segments[1].start_tick * pat.dt_s
    end = pat.timeline.segments[-1].start_tick * pat.dt_s
    walk = (t >= start) & (t < end) & np.isfinite(e).all(axis=1)
    b, a = butter(2, 2.0 / 100.0, "high")  # 2 Hz at 200 Hz
    high = filtfilt(b, a, np.nan_to_num(e), axis=0)
    f, p = welch(np.nan_to_num(e[:, 1])[walk], fs=200, nperseg=256)
    band = (f > 2) & (f < 30)
    print(
        f"{run}: rms {1e3 * np.sqrt(np.mean(np.sum(e[walk] ** 2, axis=1))):.1f} mm; above 2 Hz"
        f" {1e3 * np.sqrt(np.mean(np.sum(high[walk] ** 2, axis=1))):.1f} mm (y"
        f" {1e3 * np.sqrt(np.mean(high[walk, 1] ** 2)):.1f}, x {1e3 * np.sqrt(np.mean(high[walk, 0] ** 2)):.1f});"
        f" the lateral peak above 2 Hz at {f[band][np.argmax(p[band])]:.1f} Hz"
    )
