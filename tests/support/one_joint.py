"""A supervisor of one joint for the tests of its rules on hand-made samples."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from drivers.joint_bus import JointDevices
from hil.config import SafetySection
from hil.safety import OverloadProtection, Supervisor


def one_joint_supervisor(
    safety: SafetySection,
    period_s: float,
    limit_a: float,
    protections: Sequence[OverloadProtection] | None = None,
) -> Supervisor:
    """Limits +-1 rad, K = 2000 N m/rad, current limit `limit_a`, torque on at 0 rad."""
    supervisor = Supervisor(
        safety,
        ("joint",),
        (JointDevices("actuator 1", "link encoder node 21"),),
        np.array([-1.0]),
        np.array([1.0]),
        period_s,
        np.array([2000.0]),
        protections,
    )
    supervisor.set_current_limits(np.array([limit_a]))
    supervisor.torque_enabled(np.zeros(1))
    return supervisor
