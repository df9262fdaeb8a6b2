"""Shared loading for the walk_zmp study: a walking run's log read through the product's own
kinematics (hil/experiments/walking_kinematics.py), plus the whole CoM from the link encoders
with the stance sole flat (hil/experiments/legs.py), cached next to the run as walk_zmp.npz."""

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(ROOT))

from hil.experiments.legs import anchor_feet, leg_model, placed_configuration  # noqa: E402
from hil.experiments.walking import STEP_ON_OBJECT, WALK_DYNAMIC, WALK_SLOW  # noqa: E402
from hil.experiments.walking_kinematics import WalkingKinematics  # noqa: E402
from hil.output.rundir import load_run  # noqa: E402

EXPERIMENTS = {e.name: e for e in (WALK_SLOW, WALK_DYNAMIC, STEP_ON_OBJECT)}


def experiment_of(run_dir: Path):
    for name, exp in EXPERIMENTS.items():
        if Path(run_dir).name.startswith(name):
            return exp
    raise SystemExit(f"{run_dir}: not a walking run directory")


def load(run_dir: str | Path) -> dict:
    """Per log row: t, zmp / dzmp (measured / desired, (n, 2)), vert (n, 2) the feet's normal
    forces, links and ref (n, 12) (the plan's angles), com (n, 3) from the encoders, plancom,
    planacc (n, 3), anchors (n,)."""
    run_dir = Path(run_dir)
    cache = run_dir / "walk_zmp.npz"
    if cache.exists():
        return dict(np.load(cache))
    exp = experiment_of(run_dir)
    kin = WalkingKinematics.of(load_run(run_dir), exp)
    pat, model = exp.pattern, leg_model()
    ticks = np.clip(np.rint(kin.time_s / pat.dt_s).astype(int), 0, pat.n_ticks - 1)
    anchors = anchor_feet(pat)[ticks]
    com = np.full((kin.time_s.size, 3), np.nan)
    for k in range(kin.time_s.size):
        if np.isfinite(kin.links_rad[k]).all():
            q = placed_configuration(model, kin.links_rad[k], anchors[k], pat, ticks[k])
            com[k] = model.centre_of_mass(q)
    data = dict(
        t=kin.time_s,
        zmp=kin.zmp_m,
        dzmp=kin.desired_zmp_m,
        vert=kin.vertical_n,
        links=kin.links_rad,
        ref=pat.joint_angles_rad[ticks],
        com=com,
        plancom=pat.com_position_m[ticks],
        planacc=pat.com_acceleration_mps2[ticks],
        anchors=anchors,
        ticks=ticks,
    )
    np.savez(cache, **data)
    return data
