"""The lab's two pattern differences, on the cart-table alone (no robot): its preview uses the
CoM height above the ankle frame (its support foot frame) for zc, and it resets the preview's
previous jerk to 0 every tick (walking_controller.cpp, modifiedPreviewControl: ux_1_ = 0). The
ZMP a real robot (CoM 0.828 m above the ground) makes along each plan, against the reference.

    python docs/studies/walk_zmp/plan_variants.py
"""

import numpy as np

from common import WALK_DYNAMIC, WALK_SLOW
from controller.walking import ZmpReferenceParams, ZmpTransition
from controller.walking.dyros_jet_figures import SOLE_BELOW_ANKLE_M, SOLE_CENTRE_AHEAD_OF_ANKLE_M
from controller.walking.preview_control import (
    CartTableParams,
    PreviewWeights,
    design_preview_controller,
    track_zmp_reference,
)
from controller.walking.timeline import WalkTimeline
from controller.walking.zmp_reference import zmp_reference

DT = 0.005
params = ZmpReferenceParams(ZmpTransition.LAB_SPLIT, SOLE_CENTRE_AHEAD_OF_ANKLE_M, 0.02, 0.1)


def report(name, zmp, ref):
    err = zmp - ref
    walk = slice(320, len(ref) - 100)
    print(
        f"  {name}: y rms {1e3 * np.sqrt(np.mean(err[walk, 1] ** 2)):.1f} mm, max {1e3 * np.abs(err[walk, 1]).max():.1f};"
        f" x rms {1e3 * np.sqrt(np.mean(err[walk, 0] ** 2)):.1f}, max {1e3 * np.abs(err[walk, 0]).max():.1f}"
    )


for exp in (WALK_SLOW, WALK_DYNAMIC):
    zc = exp.pattern.params.com_height_m
    ref = zmp_reference(WalkTimeline(exp.plan, DT), params)
    print(exp.name, f"(zc {zc:.3f} m above the ground)")
    for label, height in (
        ("ours, zc above the ground", zc),
        ("the lab's zc above the ankle", zc - SOLE_BELOW_ANKLE_M),
    ):
        cart = track_zmp_reference(
            design_preview_controller(CartTableParams(height, 9.81, DT), PreviewWeights(), 1.6), ref
        )
        report(label, cart.position_m - zc / 9.81 * cart.acceleration_mps2, ref)
    gains = design_preview_controller(CartTableParams(zc, 9.81, DT), PreviewWeights(), 1.6)
    a, b, c = gains.model.matrices()
    n = gains.horizon_ticks
    padded = np.concatenate((ref, np.repeat(ref[-1:], n + 2, axis=0)))
    x = np.zeros((3, 2))
    x[0] = ref[0]
    zmp = []
    for k in range(len(ref)):
        previous = np.array([x[0] - x[1] * DT, x[1] - x[2] * DT, x[2]])
        jerk = (
            -gains.integral_gain * (c @ x - ref[k])
            - gains.state_gain @ (x - previous)
            - gains.preview_gains @ (padded[k + 1 : k + 1 + n] - padded[k : k + n])
        )
        zmp.append(c @ x)
        x = a @ x + np.outer(b, jerk)
    report("the lab's preview, previous jerk reset to 0", np.array(zmp), ref)
