"""The report's table from runs.sh's run directories: python table.py OUT"""

import json
import sys
from pathlib import Path

rows = []
for summary_path in sorted(Path(sys.argv[1]).glob("*/*/summary.json")):
    summary = json.loads(summary_path.read_text())
    meta = json.loads((summary_path.parent / "meta.json").read_text())
    design = summary_path.parent.parent.name
    metrics = summary["metrics"]
    ended = summary["termination"]
    stopped = next(iter(summary["safety_events"]), None)
    if stopped is not None:
        ended = f"safety stop {stopped['cause']} ({stopped['joint']}) at {stopped['time_s']:.2f} s"
    steps = metrics.get("steps_completed")
    fell = metrics.get("fell")
    fell_text = (
        ("yes" + (f" ({metrics['fell_at_s']:.2f} s)" if metrics.get("fell_at_s") else ""))
        if fell
        else "no"
    )
    extra = ""
    if "zmp_rms_error_m" in metrics and metrics["zmp_rms_error_m"] is not None:
        extra = f"ZMP rms {metrics['zmp_rms_error_m'] * 1e3:.0f} mm"
    if "pelvis_tilt_rad" in metrics and metrics["pelvis_tilt_rad"] is not None:
        extra += f", tilt {metrics['pelvis_tilt_rad']:.4f} rad"
    rows.append(
        (
            design,
            summary["experiment"],
            summary["controller"],
            ended,
            "" if steps is None else str(steps),
            fell_text,
            extra,
        )
    )
print("| design | experiment | controller | ended | steps | fell | |")
print("|---|---|---|---|---|---|---|")
for row in rows:
    print("| " + " | ".join(row) + " |")
