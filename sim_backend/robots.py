"""The emulated hardware of each kind a spec names (`HardwareKind`): one builder a line."""

from __future__ import annotations

from collections.abc import Callable, Mapping

from sim_backend.hardware import EmulatedHardware, EmulatedTestbed
from sim_backend.spec import EmulatorSpec, HardwareKind


def _humanoid(spec: EmulatorSpec) -> EmulatedHardware:
    from sim_backend.humanoid.hardware import EmulatedHumanoid  # the MuJoCo humanoid

    return EmulatedHumanoid.build(spec)


def _fixed_base(spec: EmulatorSpec) -> EmulatedHardware:
    from sim_backend.fixed_base.hardware import EmulatedFixedBase  # a robot from its URDF

    return EmulatedFixedBase.build(spec)


BUILDERS: Mapping[HardwareKind, Callable[[EmulatorSpec], EmulatedHardware]] = {
    HardwareKind.SINGLE_LINKS: EmulatedTestbed.build,
    HardwareKind.HUMANOID: _humanoid,
    HardwareKind.FIXED_BASE: _fixed_base,
}


def build_hardware(spec: EmulatorSpec) -> EmulatedHardware:
    """The emulated hardware `spec.robot` names (see sim_backend/hardware.py)."""
    return BUILDERS[spec.robot](spec)
