"""CAN sensors: CiA 406 link encoders, a CiA 404 force sensor (the testbed's obstacle) and
six-axis CiA 404 force/torque sensors (the humanoid's feet).

Built on python-can (the bus) and canopen (NMT, SDO); the per-tick SYNC -> TPDO path reads
the bus directly, without threads. This package never imports `sim_backend`.
"""

from drivers.canbus.config import ForceSensorConfig, ForceTorqueSensorConfig, LinkEncoderConfig
from drivers.canbus.link_encoders import CanDeviceError, LinkEncoderReader
from drivers.canbus.readings import ForceReading, LinkReading, WrenchReading
from drivers.canbus.units import (
    RLC2IC_MR075_COUNTS_PER_REV,
    force_n_from_counts,
    link_angle_rad_from_counts,
    wrench_from_counts,
)

__all__ = [
    "RLC2IC_MR075_COUNTS_PER_REV",
    "CanDeviceError",
    "ForceReading",
    "ForceSensorConfig",
    "ForceTorqueSensorConfig",
    "LinkEncoderConfig",
    "LinkEncoderReader",
    "LinkReading",
    "WrenchReading",
    "force_n_from_counts",
    "link_angle_rad_from_counts",
    "wrench_from_counts",
]
