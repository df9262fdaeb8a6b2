"""A fixed-base robot's emulated hardware from a configuration: its URDF with a flexible joint
per [[joint]] (sim_backend/fixed_base/), each joint's gear and servo its actuator model's,
`[emulator] plant` overriding `FixedBaseTruthParams`; at power-on at rest, statically loaded,
at the experiment's first reference (else every joint at 0, within its limits); the
experiment's block and pushes at the tool."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from hil.config import Config, robot_description_text
from hil.experiments import Experiment
from hil.robots.profile import JointTruth, RobotEmulation
from sim_backend.fixed_base.params import FixedBaseTruthParams
from sim_backend.plant import TestbedPlantParams
from sim_backend.servo import H54ServoParams
from sim_backend.servo_models import servo_params_for
from sim_backend.spec import BlockSpec, FixedBaseSpec, HardwareKind, ToolPushSpec


def _models(config: Config) -> list[str]:
    return [config.actuator_of(joint) for joint in config.joints]


class FixedBaseEmulation(RobotEmulation):
    kind = HardwareKind.FIXED_BASE

    def plant(self, config: Config, overrides: Mapping[str, Any]) -> TestbedPlantParams:
        """The robot's truth checked (per-joint figures against its joints); the spec's
        testbed plant is unused (its defaults)."""
        FixedBaseTruthParams(**overrides).gears(_models(config))
        return TestbedPlantParams()

    def joint_truth(self, config: Config, servo: H54ServoParams) -> JointTruth:
        models = _models(config)
        gears = FixedBaseTruthParams(**dict(config.emulator.plant)).gears(models)
        servos = tuple(servo_params_for(model, servo) for model in models)
        return JointTruth(
            tuple(g.gear_stiffness_nm_per_rad for g in gears),
            servos,
            tuple(s.default_position_gain_register for s in servos),
        )

    def spec_parts(
        self, config: Config, start_rad: np.ndarray | None, experiment: Experiment | None
    ) -> dict[str, Any]:
        model = config.model
        if start_rad is None:  # no experiment: every joint at 0, within its limits
            start_rad = np.array(
                [np.clip(0.0, j.min_angle_rad, j.max_angle_rad) for j in config.joints]
            )
        world = experiment.world if experiment is not None else None
        block = world.block if world is not None else None
        spec = FixedBaseSpec(
            urdf_text=robot_description_text(config),
            joint_names=config.joint_names,
            initial_angles_rad=tuple(float(a) for a in start_rad),
            locked_angles_rad=dict(model.locked_joint_angles_rad),
            tool_link=model.tool_link or "",
            tool_point_m=tuple(model.tool_point_m),
            block=BlockSpec(tuple(block.centre_m), tuple(block.size_m)) if block else None,
            tool_pushes=tuple(
                ToolPushSpec(p.start_s, p.duration_s, tuple(p.force_n))
                for p in (world.tool_pushes if world is not None else ())
            ),
            truth=dict(config.emulator.plant),
        )
        return {"fixed_base": spec}
