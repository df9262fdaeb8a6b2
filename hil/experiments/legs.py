"""DYROS-JET's legs as the humanoid experiments see them: the controller's model, and a measured
posture placed on the ground.

    leg_model            the controller's pinocchio model of the built-in DYROS-JET (one, cached)
    pelvis_rotation      world <- pelvis of a configuration q
    anchor_feet          per tick of a walking pattern, the foot that carried the robot longest
    placed_configuration link angles with one sole flat at its planned place: q, frames updated

The standing experiments (humanoid.py), the walking metrics and figures (walking_kinematics.py,
walking_figures.py) and the lab's walking scheme (walking_scheme.py) read the robot through
these: what the robot's own encoders say, through the same model, the same way.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np


@functools.lru_cache(maxsize=1)
def leg_model() -> Any:
    """The controller's `controller.humanoid.LegModel` of the built-in DYROS-JET (shared: its
    pinocchio data is scratch space, so use it from one thread)."""
    from controller.humanoid import LegModel
    from hil.config import load_config, robot_description_text

    return LegModel(robot_description_text(load_config(robot="dyros-jet")))


def support_state(support: Any) -> Any:
    """A walking pattern's `controller.walking.Support` as the model's `SupportState`."""
    from controller.humanoid import SupportState

    return SupportState(support.value)


def pelvis_rotation(q: np.ndarray) -> np.ndarray:
    """world <- pelvis of pinocchio's configuration q (its free-flyer quaternion x, y, z, w)."""
    import pinocchio as pin

    return pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()


def anchor_feet(pattern: Any) -> np.ndarray:
    """Per pattern tick, the foot that carried the robot longest: the stance foot of the latest
    single support (before the first one, the stance foot of the first)."""
    from controller.walking import SegmentKind

    segments = pattern.timeline.segments
    singles = [s for s in segments if s.kind is SegmentKind.SINGLE_SUPPORT]
    anchors = np.empty(pattern.n_ticks, dtype=int)
    current = singles[0].landing_side.other.index
    for segment in segments:
        if segment.kind is SegmentKind.SINGLE_SUPPORT:
            current = segment.landing_side.other.index
        anchors[segment.start_tick : segment.end_tick] = current
    return anchors


def placed_configuration(
    model: Any, links: np.ndarray, anchor: int, pattern: Any, tick: int
) -> np.ndarray:
    """pinocchio's q at these link angles with sole `anchor` flat on the ground at its planned
    place (the pattern's foot at `tick`, carried to the sole's centre), frames updated."""
    from controller.walking import yaw_rotation

    q = model.standing_configuration(links, side=anchor)  # that sole's centre at the origin
    yaw = float(pattern.foot_yaw_rad[tick, anchor])
    turn = yaw_rotation(yaw)
    sole_in_ankle = model.sole_boxes[anchor].bottom_centre_m
    ankle = pattern.foot_position_m[tick, anchor]
    sole = ankle + turn @ sole_in_ankle
    sole[2] = 0.0
    if yaw != 0.0:
        import pinocchio as pin

        rotation = turn @ pelvis_rotation(q)
        q[3:7] = pin.Quaternion(rotation).coeffs()
        q[:3] = turn @ q[:3]
    q[:3] += sole
    model.update_kinematics(q)
    return q
