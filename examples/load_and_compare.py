"""Load runs for analysis, and compare them: the emulated testbed's contact experiment (Fig. 5)
for 4 s with the actuator's own position control (pid) and with the paper's controller
(gc+lqr+dob), then

- the loader (`hil.load_run`): each run's signals as numpy arrays, and its whole log
  as one long table, a row per tick and joint (a pandas DataFrame with the `analysis` extra:
  pip install 'flexjoint-hil[analysis]');
- a figure of your own from the arrays: both runs' contact force (contact_force.png);
- `hil compare` on the two run directories: figures, the metrics side by side, report.md.

    python examples/load_and_compare.py

The same two runs from the command line:
    hil run contact --controller pid --duration 4
    hil run contact --controller gc+lqr+dob --duration 4
Runs go to runs/ (HIL_EXAMPLE_OUT names another folder); about 10 s in all.
"""

import os
import subprocess
import sys
from pathlib import Path

import hil

out = Path(os.environ.get("HIL_EXAMPLE_OUT", "runs"))
testbed = hil.open_robot(robot="testbed", out_root=out)
paths = [testbed.run("contact", name, duration_s=4.0).out_dir for name in ("pid", "gc+lqr+dob")]

runs = [hil.load_run(path) for path in paths]
for run in runs:
    force = run.signal("contact_force_n")  # a run-wide sensor: no joint to name
    deflection = run.signal("deflection_rad")  # the testbed's one joint: no need to name it
    touching = force > 1.0
    print(
        f"{run.controller}: {run.termination}; contact force peak {force.max():.1f} N, "
        f"mean in contact {force[touching].mean():.1f} N; largest deflection "
        f"{abs(deflection).max():.4f} rad"
    )

# The long table: a row per (tick, joint), a column per signal (tidy data).
table = runs[1].long()
try:
    frame = table.to_pandas()
except ImportError as exc:
    print(f"(without pandas: {exc})")
else:
    current = frame.groupby("phase")["motor_current_a"].agg(lambda a: a.abs().max())
    print(f"{runs[1].controller}: largest |motor current| by phase [A]:\n{current.round(2)}")

# A figure of your own (matplotlib without a display, as hil's own plots).
from matplotlib.figure import Figure  # noqa: E402

figure = Figure(figsize=(8, 4), layout="constrained")
ax = figure.subplots()
for run in runs:
    ax.plot(run.time_s, run.signal("contact_force_n"), label=run.controller)
ax.set_xlabel("time [s]")
ax.set_ylabel("contact force [N]")
ax.legend()
figure.savefig(out / "contact_force.png", dpi=100)
print(f"figure: {out / 'contact_force.png'}")

# Both runs side by side, as `hil compare RUN_DIR RUN_DIR` does from the command line.
compare = [sys.executable, "-m", "hil", "compare", *map(str, paths), "--out", str(out / "compare")]
raise SystemExit(subprocess.run(compare).returncode)
