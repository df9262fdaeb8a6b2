"""The robots the emulator can be, by name: the testbed or DYROS-JET's legs."""

from __future__ import annotations

from sim_backend.hardware import EmulatedHardware, EmulatedTestbed
from sim_backend.spec import EmulatorSpec


def build_hardware(spec: EmulatorSpec) -> EmulatedHardware:
    """The emulated hardware `spec.robot` names (see sim_backend/hardware.py)."""
    if spec.robot == "dyros-jet":
        from sim_backend.humanoid.hardware import EmulatedHumanoid  # the MuJoCo humanoid

        return EmulatedHumanoid.build(spec)
    return EmulatedTestbed.build(spec)
