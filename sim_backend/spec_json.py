"""An `EmulatorSpec` as JSON and back: how `hil run` hands its embedded emulator the robot to be
(`python -m sim_backend --spec-file`), readable without loading anything but sim_backend."""

from __future__ import annotations

import dataclasses
import json

from sim_backend.plant import ObstacleParams, TestbedPlantParams
from sim_backend.scenario import Scenario
from sim_backend.servo import H54ServoParams
from sim_backend.spec import (
    BlockSpec,
    EmulatedJointSpec,
    EmulatorSpec,
    FixedBaseSpec,
    FloorBox,
    HumanoidSpec,
    SensorNoise,
    ToolPushSpec,
)


def spec_to_json(spec: EmulatorSpec) -> str:
    return json.dumps(dataclasses.asdict(spec))


def spec_from_json(text: str) -> EmulatorSpec:
    raw = json.loads(text)
    plant = dict(raw["plant"])
    obstacle = plant.pop("obstacle", None)
    humanoid = raw.get("humanoid")
    return EmulatorSpec(
        joints=tuple(EmulatedJointSpec(**j) for j in raw["joints"]),
        baudrate=raw["baudrate"],
        can_bitrate=raw["can_bitrate"],
        force_sensor_node_id=raw["force_sensor_node_id"],
        period_s=raw["period_s"],
        clock=raw["clock"],
        seed=raw["seed"],
        plant=TestbedPlantParams(
            **plant, obstacle=ObstacleParams(**obstacle) if obstacle else None
        ),
        servo=H54ServoParams(**raw["servo"]),
        scenario=Scenario.from_dict(raw["scenario"]),
        reboot_time_s=raw["reboot_time_s"],
        heartbeat_ms=raw["heartbeat_ms"],
        sensor_noise=SensorNoise(**raw["sensor_noise"]),
        usb_latency_timer_s=raw["usb_latency_timer_s"],
        can_bootup_delay_s=raw["can_bootup_delay_s"],
        truth_log=raw.get("truth_log", ""),
        chain_baudrates=tuple(raw.get("chain_baudrates", ())),
        robot=raw["robot"],
        humanoid=HumanoidSpec(
            urdf_text=humanoid["urdf_text"],
            ft_sensor_node_ids=tuple(humanoid["ft_sensor_node_ids"]),
            initial_leg_angles_rad=tuple(humanoid["initial_leg_angles_rad"]),
            support_feet=tuple(humanoid["support_feet"]),
            truth=humanoid["truth"],
            floor_boxes=tuple(FloorBox(**box) for box in humanoid.get("floor_boxes", ())),
            suspended=bool(humanoid.get("suspended", False)),
        )
        if humanoid
        else None,
        fixed_base=_fixed_base(raw.get("fixed_base")),
    )


def _fixed_base(raw: dict | None) -> FixedBaseSpec | None:
    if raw is None:
        return None
    block = raw.get("block")
    return FixedBaseSpec(
        urdf_text=raw["urdf_text"],
        joint_names=tuple(raw["joint_names"]),
        initial_angles_rad=tuple(raw["initial_angles_rad"]),
        locked_angles_rad=dict(raw["locked_angles_rad"]),
        tool_link=raw["tool_link"],
        tool_point_m=tuple(raw["tool_point_m"]),
        tool_radius_m=raw["tool_radius_m"],
        block=BlockSpec(tuple(block["centre_m"]), tuple(block["size_m"])) if block else None,
        tool_pushes=tuple(
            ToolPushSpec(p["start_s"], p["duration_s"], tuple(p["force_n"]))
            for p in raw["tool_pushes"]
        ),
        truth=raw["truth"],
    )
