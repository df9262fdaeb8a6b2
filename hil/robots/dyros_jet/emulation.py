"""The emulated DYROS-JET from a configuration: its 12 leg joints on one MuJoCo robot generated
from the URDF (sim_backend/humanoid/), `[emulator] plant` overriding its truth
(`RobotTruthParams`), standing at power-on in the experiment's first posture (else the
walking-ready one) - or hung by its pelvis for an experiment whose world is suspended - the
feet's force/torque sensors on CAN."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from hil.config import Config, robot_description_text
from hil.experiments import Experiment
from hil.robots.profile import JointTruth, RobotEmulation
from sim_backend.plant import TestbedPlantParams
from sim_backend.servo import H54ServoParams
from sim_backend.spec import FloorBox, HardwareKind, HumanoidSpec


class HumanoidEmulation(RobotEmulation):
    kind = HardwareKind.HUMANOID

    def plant(self, config: Config, overrides: Mapping[str, Any]) -> TestbedPlantParams:
        """The humanoid's truth checked; the spec's testbed plant is unused (its defaults)."""
        from sim_backend.humanoid.params import RobotTruthParams

        RobotTruthParams(**overrides)
        return TestbedPlantParams()

    def joint_truth(self, config: Config, servo: H54ServoParams) -> JointTruth:
        from sim_backend.humanoid.params import RobotTruthParams

        truth = RobotTruthParams(**{"servo": servo, **dict(config.emulator.plant)})
        n = len(config.joints)
        return JointTruth(
            truth.per_joint("gear_stiffness_nm_per_rad"),
            tuple(truth.servo_params(i) for i in range(n)),
            tuple(truth.position_gain_registers),
        )

    def spec_parts(
        self, config: Config, start_rad: np.ndarray | None, experiment: Experiment | None
    ) -> dict[str, Any]:
        """Its description, foot sensors, the posture it stands in at power-on (the
        experiment's first reference; else the walking-ready posture), and the objects on the
        floor of the experiment's world."""
        from controller.humanoid import WALKING_READY_LEG_ANGLES_RAD

        node_ids = {sensor.name: sensor.node_id for sensor in config.force_torque_sensors}
        posture = (
            WALKING_READY_LEG_ANGLES_RAD
            if start_rad is None
            else tuple(float(a) for a in start_rad)
        )
        humanoid = HumanoidSpec(
            urdf_text=robot_description_text(config),
            ft_sensor_node_ids=(node_ids.get("left_foot", 0), node_ids.get("right_foot", 0)),
            initial_leg_angles_rad=posture,
            truth=dict(config.emulator.plant),
            floor_boxes=tuple(
                FloorBox(tuple(o.centre_m), tuple(o.size_m))
                for o in (experiment.world.floor_objects if experiment is not None else ())
            ),
            suspended=experiment is not None and experiment.world.suspended,
        )
        return {"humanoid": humanoid}
