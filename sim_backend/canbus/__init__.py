"""Emulated CAN hardware: CiA 406 link encoders, a CiA 404 force sensor, six-axis CiA 404
force/torque sensors, a bus segment, and a Lawicel-SLCAN adapter on a pty.

The nodes are pure frame handlers (`handle(msg, now_s)`, `poll(now_s)`) with the emulator's
clock passed in; `CanSegment` joins them into one bus; `NodeRunner` serves a segment on a
python-can bus in-process; `SlcanPty` serves it to another process through a serial port.
"""

from sim_backend.canbus.encoder_node import EncoderFault, LinkEncoderNode
from sim_backend.canbus.force_sensor_node import ForceSensorNode
from sim_backend.canbus.ft_sensor_node import ForceTorqueSensorNode
from sim_backend.canbus.segment import CanNode, CanSegment, NodeRunner
from sim_backend.canbus.slave import FAULT_MODES, SensorFault
from sim_backend.canbus.slcan_pty import SlcanPty

__all__ = [
    "FAULT_MODES",
    "CanNode",
    "CanSegment",
    "EncoderFault",
    "ForceSensorNode",
    "ForceTorqueSensorNode",
    "LinkEncoderNode",
    "NodeRunner",
    "SensorFault",
    "SlcanPty",
]
