"""`hil model [--robot R | --config FILE] [--json]`: each joint's static stiffness, as the
controller's model has it and as the emulated robot is built.

A joint is its gear spring K in series with its position servo's static stiffness Kpp kv (the
H54's position gain times its velocity P gain; its velocity integral winds the servo's part out
over Ti). The gravity compensator (8) offsets ug = C tau_g with C = 1/K + 1/(Kpp kv) ("joint")
or the paper's 1/K ("gear"), `[controller] gc_compliance` (controller/gravity.py). This command
prints, per joint:
- the controller's model ([model], [model.joint.NAME]): K, Kpp, kv, Ti, Kpp kv and both
  readings of C, and which one the configuration runs;
- the emulated robot the same configuration builds (`hil emulate`): its gear, its servo at the
  gain registers the run leaves it with, and its C.
Nothing is sent to any device.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from controller import GcCompliance
from hil.cli.common import checked_config
from hil.cli.exit_codes import ExitCode
from hil.config import Config
from hil.controllers.paper_factory import gc_compliance, model_figures
from hil.wiring.emulation import emulated_joint_stiffness

COLUMNS = (
    ("joint", "", "{}"),
    ("K", "N m/rad", "{:.0f}"),
    ("Kpp", "1/s", "{:.3g}"),
    ("kv", "N m s/rad", "{:.4g}"),
    ("Ti", "s", "{:.3g}"),
    ("Kpp kv", "N m/rad", "{:.0f}"),
    ("C joint", "rad/N m", "{:.6f}"),
    ("C gear", "rad/N m", "{:.6f}"),
    ("emulated K", "N m/rad", "{:.0f}"),
    ("emulated Kpp kv", "N m/rad", "{:.0f}"),
    ("emulated Ti", "s", "{:.3g}"),
    ("emulated C", "rad/N m", "{:.6f}"),
)


def joint_table(config: Config) -> list[dict[str, Any]]:
    """One row per joint: the controller's model and the emulated joint (module docstring)."""
    stiffness = model_figures(config, "stiffness_nm_per_rad")
    position = model_figures(config, "position_gain_per_s")
    velocity = model_figures(config, "velocity_gain_nms_per_rad")
    integral = model_figures(config, "velocity_integral_time_s")
    joint = gc_compliance(config, GcCompliance.JOINT)
    gear = gc_compliance(config, GcCompliance.GEAR)
    rows = []
    for i, emulated in enumerate(emulated_joint_stiffness(config)):
        rows.append(
            {
                "joint": config.joint_names[i],
                "K": float(stiffness[i]),
                "Kpp": float(position[i]),
                "kv": float(velocity[i]),
                "Ti": float(integral[i]),
                "Kpp kv": float(position[i] * velocity[i]),
                "C joint": float(joint[i]),
                "C gear": float(gear[i]),
                "emulated K": emulated.gear_stiffness_nm_per_rad,
                "emulated Kpp kv": emulated.servo.static_stiffness_nm_per_rad,
                "emulated Ti": emulated.servo.velocity_integral_time_s,
                "emulated C": emulated.compliance_rad_per_nm,
            }
        )
    return rows


def cmd_model(args: argparse.Namespace) -> int:
    config = checked_config(args.config, args.robot)
    rows = joint_table(config)
    reading = GcCompliance(config.controller.gc_compliance)
    if args.json:
        record = {"source": config.source, "gc_compliance": str(reading), "joints": rows}
        print(json.dumps(record))
        return ExitCode.OK
    out = sys.stdout
    out.write(
        f"{config.source}: each joint's static compliance C = 1/K + 1/(Kpp kv) (the gear in "
        "series with the position servo, before its velocity integral grows)\n"
        f"the gravity compensator (8) runs ug = C tau_g with C {reading.value!r} "
        "([controller] gc_compliance)\n\n"
    )
    cells = [[fmt.format(row[key]) for key, _, fmt in COLUMNS] for row in rows]
    heads = [key for key, _, _ in COLUMNS]
    units = [f"[{unit}]" if unit else "" for _, unit, _ in COLUMNS]
    widths = [
        max(len(h), len(u), *(len(c[i]) for c in cells))
        for i, (h, u) in enumerate(zip(heads, units, strict=True))
    ]
    for line in (heads, units, *cells):
        padded = [v.rjust(w) for v, w in zip(line, widths, strict=True)]
        out.write("  ".join([line[0].ljust(widths[0]), *padded[1:]]) + "\n")
    return ExitCode.OK
