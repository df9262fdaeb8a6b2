"""The configuration file: one TOML file describes the hardware, the robot model, the controller,
the safety limits and the emulator.

The same file drives the real robot (`hil run --config FILE`) and its emulation
(`hil emulate --config FILE`). A sample for the paper's testbed ships as `hil/data/testbed.toml`
(`hil config` prints it). The schema is declared once (`schema.py`, pydantic); command-line
options go through the same validation (`Config.changed`).
"""

from hil.config.control_sections import ControllerSection, ModelSection, WalkingSection
from hil.config.load import (
    BUILT_IN_CONFIGS,
    DEFAULT_CONFIG_NAME,
    Config,
    ConfigError,
    builtin_config_name,
    config_from_record,
    default_config_text,
    load_config,
    parse_config,
    robot_description_text,
    robot_of,
)
from hil.config.schema import (
    CanSection,
    DynamixelSection,
    EmulatorSection,
    ForceSensorSection,
    JointSection,
    LoopSection,
    SafetySection,
)

__all__ = [
    "BUILT_IN_CONFIGS",
    "DEFAULT_CONFIG_NAME",
    "CanSection",
    "Config",
    "ConfigError",
    "ControllerSection",
    "DynamixelSection",
    "EmulatorSection",
    "ForceSensorSection",
    "JointSection",
    "LoopSection",
    "ModelSection",
    "SafetySection",
    "WalkingSection",
    "builtin_config_name",
    "config_from_record",
    "default_config_text",
    "load_config",
    "parse_config",
    "robot_description_text",
    "robot_of",
]
