"""The robots hil knows: one line a robot (its profile, in its own folder)."""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

from hil.robots import dyros_jet, fixed_base, manipulator_h, testbed
from hil.robots.profile import RobotProfile
from hil.vocabulary import Robot

PROFILES: Mapping[Robot, RobotProfile] = MappingProxyType(
    {
        Robot.TESTBED: testbed.PROFILE,
        Robot.DYROS_JET: dyros_jet.PROFILE,
        Robot.FIXED_BASE: fixed_base.PROFILE,
        Robot.MANIPULATOR_H: manipulator_h.PROFILE,
    }
)
