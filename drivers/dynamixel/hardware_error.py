"""The Dynamixel Pro's Hardware Error Status bits and what they mean in vendor-neutral terms.

Source: ROBOTIS e-Manual, H54-200-S500-R, "Shutdown" (48) and "Hardware Error Status" (892);
bits 7 and 6 are unused. The loop sees only `drivers.joint_bus.ActuatorFault`; the bits stay here.
"""

from __future__ import annotations

import enum

from drivers.joint_bus import ActuatorFault


class HardwareError(enum.IntFlag):
    """Bits of Hardware Error Status (892) and of the Shutdown mask (48)."""

    INPUT_VOLTAGE = 0x01
    MOTOR_HALL_SENSOR = 0x02
    OVERHEATING = 0x04
    MOTOR_ENCODER = 0x08
    ELECTRICAL_SHOCK = 0x10
    OVERLOAD = 0x20

    @classmethod
    def describe(cls, bits: int) -> str:
        """'OVERLOAD|OVERHEATING' for the set bits, 'none' for 0."""
        names = [flag.name for flag in cls if bits & flag and flag.name]
        return "|".join(names) if names else "none"


_FAULT_OF_BIT = {
    HardwareError.INPUT_VOLTAGE: ActuatorFault.SUPPLY_VOLTAGE,
    HardwareError.MOTOR_HALL_SENSOR: ActuatorFault.MOTOR_SENSOR,
    HardwareError.OVERHEATING: ActuatorFault.OVERHEATING,
    HardwareError.MOTOR_ENCODER: ActuatorFault.MOTOR_SENSOR,
    HardwareError.ELECTRICAL_SHOCK: ActuatorFault.ELECTRICAL,
    HardwareError.OVERLOAD: ActuatorFault.OVERLOAD,
}
_KNOWN_BITS = sum(int(bit) for bit in HardwareError)


def actuator_fault(bits: int) -> ActuatorFault:
    """The vendor-neutral faults a Hardware Error Status value reports (unknown bits: OTHER)."""
    fault = ActuatorFault(0)
    for bit, kind in _FAULT_OF_BIT.items():
        if bits & bit:
            fault |= kind
    if bits & ~_KNOWN_BITS & 0xFF:
        fault |= ActuatorFault.OTHER
    return fault
