"""The emulated testbed from a configuration: a MuJoCo plant per joint behind its firmware
(sim_backend/testbed.py), `[emulator] plant` overriding `TestbedPlantParams`."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from hil.config import Config
from hil.robots.profile import JointTruth, RobotEmulation
from sim_backend.plant import TestbedPlantParams
from sim_backend.servo import H54ServoParams
from sim_backend.servo_models import servo_params_for
from sim_backend.spec import HardwareKind


class TestbedEmulation(RobotEmulation):
    __test__ = False  # not a pytest test class
    kind = HardwareKind.SINGLE_LINKS

    def plant(self, config: Config, overrides: Mapping[str, Any]) -> TestbedPlantParams:
        return TestbedPlantParams(**overrides)

    def start_overrides(self, start_rad: np.ndarray) -> dict[str, Any]:
        """The link hangs where the experiment starts (every joint is a copy of one plant)."""
        return {"initial_link_angle_rad": float(start_rad[0])}

    def joint_truth(self, config: Config, servo: H54ServoParams) -> JointTruth:
        plant = self.plant(config, config.emulator.plant)
        servos = tuple(servo_params_for(config.actuator_of(j), servo) for j in config.joints)
        return JointTruth(
            (plant.gear_stiffness_nm_per_rad,) * len(servos),
            servos,
            tuple(s.default_position_gain_register for s in servos),
        )
