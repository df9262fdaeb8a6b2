"""CAN sensors of the testbed: CiA 406 link encoders and a CiA 404 force sensor.

Built on python-can (the bus) and canopen (NMT, SDO); the per-tick SYNC -> TPDO path reads
the bus directly, without threads. This package never imports `sim_backend`.
"""

from drivers.canbus.config import ForceSensorConfig, LinkEncoderConfig
from drivers.canbus.link_encoders import CanDeviceError, LinkEncoderReader
from drivers.canbus.readings import ForceReading, LinkReading
from drivers.canbus.units import (
    RLC2IC_MR075_COUNTS_PER_REV,
    force_n_from_counts,
    link_angle_rad_from_counts,
)

__all__ = [
    "RLC2IC_MR075_COUNTS_PER_REV",
    "CanDeviceError",
    "ForceReading",
    "ForceSensorConfig",
    "LinkEncoderConfig",
    "LinkEncoderReader",
    "LinkReading",
    "force_n_from_counts",
    "link_angle_rad_from_counts",
]
