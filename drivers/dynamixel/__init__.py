"""DYNAMIXEL PRO driver on the unmodified `dynamixel-sdk` (Protocol 2.0): every model of the
family with a published control table (`ACTUATOR_MODELS`, drivers/dynamixel/models.py), mixed
on one chain as the joints' configuration says.

- `DynamixelChain`: a chain of actuators on one port (state block by one sync read, goals by one
  sync write, enable / disable / reboot, hardware-error reporting), SI units at its interface.
- `scan` / `scan_bauds`: which devices answer on a port (progress callback, time budget).
- `bench_bus`: the chain's tick against a bare SDK loop.
"""

from drivers.dynamixel.bench import BusBenchResult, CycleStats, bench_bus
from drivers.dynamixel.chain import (
    DeviceInfo,
    DynamixelChain,
    DynamixelState,
    HardwareErrorStatus,
)
from drivers.dynamixel.config import DynamixelChainConfig, DynamixelJointConfig
from drivers.dynamixel.control_table import (
    MODELS,
    REGISTERS,
    ControlItem,
    ModelSpec,
    model_name,
    model_number,
    model_spec,
)
from drivers.dynamixel.errors import (
    DeviceShutdownError,
    DynamixelReplyError,
    EepromChangeRefused,
    PortGoneError,
)
from drivers.dynamixel.hardware_error import HardwareError, actuator_fault
from drivers.dynamixel.models import ACTUATOR_MODELS, ActuatorModel, Layout
from drivers.dynamixel.port import LowLatencyPortHandler, open_port
from drivers.dynamixel.scan import (
    FoundDevice,
    ScanProgress,
    ScanReport,
    ScanStep,
    scan,
    scan_bauds,
)
from drivers.dynamixel.units import H54_200_S500_R_UNITS, ChainUnits, DeviceUnits

__all__ = [
    "ACTUATOR_MODELS",
    "H54_200_S500_R_UNITS",
    "MODELS",
    "REGISTERS",
    "ActuatorModel",
    "BusBenchResult",
    "ChainUnits",
    "ControlItem",
    "CycleStats",
    "DeviceInfo",
    "DeviceShutdownError",
    "DeviceUnits",
    "DynamixelChain",
    "DynamixelChainConfig",
    "DynamixelJointConfig",
    "DynamixelReplyError",
    "DynamixelState",
    "EepromChangeRefused",
    "FoundDevice",
    "HardwareError",
    "HardwareErrorStatus",
    "Layout",
    "LowLatencyPortHandler",
    "ModelSpec",
    "PortGoneError",
    "ScanProgress",
    "ScanReport",
    "ScanStep",
    "actuator_fault",
    "bench_bus",
    "model_name",
    "model_number",
    "model_spec",
    "open_port",
    "scan",
    "scan_bauds",
]
