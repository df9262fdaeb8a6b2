"""Bring-up: looking at a robot before running anything on it, and setting its zero offsets.

monitor.py       `hil monitor`: every joint's readings at a steady rate, judged against the
                 configuration's limits (read-only: nothing is written to any actuator)
calibration.py   `hil calibrate`: zero offsets and direction agreement measured at the
                 reference pose, and the configuration file updated in place
"""

from hil.bringup.calibration import (
    Calibration,
    DirectionCheck,
    JointCalibration,
    calibrate,
    calibration_fragment,
    update_config_text,
)
from hil.bringup.monitor import Flag, JointStatus, MonitorSample, assess, monitor

__all__ = [
    "Calibration",
    "DirectionCheck",
    "Flag",
    "JointCalibration",
    "JointStatus",
    "MonitorSample",
    "assess",
    "calibrate",
    "calibration_fragment",
    "monitor",
    "update_config_text",
]
