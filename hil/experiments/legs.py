"""DYROS-JET's legs as the humanoid experiments see them: the controller's model, and a measured
posture placed on the ground.

    leg_model            the controller's pinocchio model of the built-in DYROS-JET (one, cached)
    pelvis_rotation      world <- pelvis of a configuration q
    anchor_feet          per tick of a walking pattern, the foot that carried the robot longest
    placed_configuration link angles with one sole flat at its planned place: q, frames updated
    on_feet              how a robot on its feet does the supervisor's reactions (every
                         humanoid experiment's `reaction_policy`), and `FeetCarryTheRobot`, its rest

The standing experiments (humanoid.py), the walking metrics and figures (walking_kinematics.py,
walking_figures.py) and the lab's walking scheme (walking_scheme.py) read the robot through
these: what the robot's own encoders say, through the same model, the same way.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from drivers.joint_bus import JointSample, wrench_keys
from hil.vocabulary import Reaction, ReactionPolicy, RestCondition, Robot

FEET = ("left_foot", "right_foot")  # the feet's force/torque sensors ([[force_torque_sensor]])
GRAVITY_M_S2 = 9.81
# The rest a `finish_step` ends in: each foot carries at least REST_SHARE of what the two carry,
# the two at least REST_LOAD_SHARE of the weight, for REST_TICKS ticks in a row (50 ms at
# 200 Hz). Why these: a double support with the weight shared is what the robot can be held in
# (the CoM between the feet); a walk's double support shares it for most of its length (the
# lab's ZMP moves in 0.1 s at each end), while a touchdown that rocks back onto the other
# foot shares it only briefly and less (the pid walk-slow at 13.40 s: 21-34 % for 30 ms).
REST_SHARE = 0.25
REST_LOAD_SHARE = 0.5
REST_TICKS = 10


class FeetCarryTheRobot(RestCondition):
    """Both feet on the ground, carrying the robot between them (the thresholds above)."""

    def __init__(self, weight_n: float) -> None:
        self.weight_n = weight_n
        self._keys = tuple(wrench_keys(foot)[2] for foot in FEET)  # fz: the sole's normal
        self._ticks = 0

    def reached(self, sample: JointSample) -> str | None:
        left, right = (float(sample.extra.get(key, np.nan)) for key in self._keys)
        total = left + right
        shared = min(left, right) >= REST_SHARE * total and total >= REST_LOAD_SHARE * self.weight_n
        self._ticks = self._ticks + 1 if shared else 0  # (False for NaN: a sensor not read)
        if self._ticks < REST_TICKS:
            return None
        return (
            f"both feet carry the robot: left {left:.0f} N ({left / total:.0%}), right "
            f"{right:.0f} N ({right / total:.0%}) for {self._ticks} ticks"
        )

    def describe(self) -> str:
        return (
            f"both feet carry the robot (each >= {REST_SHARE:.0%} of the load, together >= "
            f"{REST_LOAD_SHARE:.0%} of its weight, {REST_TICKS} ticks in a row)"
        )


def on_feet(within_s: float) -> ReactionPolicy:
    """How a robot on its feet does the reactions: `back_off` (each joint moved off along its
    own current, which throws a standing or walking robot over) is done as `finish_step` (the
    controller finishes the step, the supervisor holds once both feet carry the robot);
    `within_s`: the longest a step takes to its double support (then it holds anyway). The
    others as configured: `hold` holds the posture (on one foot in a single support: standing,
    the CoM over the stance foot), `torque_off` is a fall whatever the robot (the configured
    causes are the actuator's own shutdown and a lost bus; docs/safety.md)."""
    weight_n = float(leg_model().total_mass_kg) * GRAVITY_M_S2
    return ReactionPolicy(
        instead={Reaction.BACK_OFF: Reaction.FINISH_STEP},
        rest=FeetCarryTheRobot(weight_n),
        within_s=within_s,
    )


@functools.lru_cache(maxsize=1)
def leg_model() -> Any:
    """The controller's `controller.humanoid.LegModel` of the built-in DYROS-JET (shared: its
    pinocchio data is scratch space, so use it from one thread)."""
    from controller.humanoid import LegModel
    from hil.config import load_config, robot_description_text

    return LegModel(robot_description_text(load_config(robot=Robot.DYROS_JET)))


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
