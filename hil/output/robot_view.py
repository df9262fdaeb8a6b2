"""The robot in 3D for Foxglove, in run.mcap and on the live view: the robot's frames and its
description in Foxglove's own schemas, beside the run log's channels (which are unchanged).

    /tf                 foxglove.FrameTransforms (protobuf, the schema the foxglove-sdk ships)
                        per tick: the moving joints' transforms (hil/output/robot_frames.py;
                        the humanoid's base by leg odometry, said in the channel's metadata)
    /tf_static          foxglove.FrameTransforms: every other joint's, at the start and again
                        every STATIC_EVERY_S (a viewer that seeks finds them within that)
    /robot_description  the URDF with shapes to draw, JSON {"data": URDF} under the schema
                        name std_msgs/msg/String: what the 3D panel's URDF layer takes from a
                        topic (Source: Topic, /robot_description); at the start and every
                        STATIC_EVERY_S

In Foxglove: a 3D panel, Display frame `world`; add a custom layer "URDF", Source "Topic",
Topic /robot_description. The frames are computed from each tick's /joints message; with the
live view (the log in the loop's process) on every LIVE_EVERY_TICKS-th tick only.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from hil.output.channels import Channel, ChannelSet, encode
from hil.output.robot_description import RunRobot
from hil.output.robot_frames import FrameTransform, RobotFrames, robot_frames
from hil.output.tick_sample import TickSample

if TYPE_CHECKING:
    from collections.abc import Sequence

TF_TOPIC, TF_STATIC_TOPIC, DESCRIPTION_TOPIC = "/tf", "/tf_static", "/robot_description"
DESCRIPTION_SCHEMA = "std_msgs/msg/String"
STATIC_EVERY_S = 1.0
LIVE_EVERY_TICKS = 4  # 50 Hz: forward kinematics in the loop's process costs ~0.1 ms a tick


@dataclass(frozen=True)
class ViewMessage:
    channel: Channel
    time_s: float
    data: bytes


class RobotView:
    """The 3D view's channels (added to the run's ChannelSet) and messages."""

    def __init__(self, robot: RunRobot, channels: ChannelSet, every_ticks: int = 1) -> None:
        import foxglove.messages as fm

        self._fm = fm
        frames = robot_frames(robot)
        assert frames is not None and robot.viewer_urdf is not None
        self.frames: RobotFrames = frames
        self.every_ticks = every_ticks
        schema = fm.FrameTransforms.get_schema()
        protobuf = {
            "message_encoding": "protobuf",
            "schema_encoding": schema.encoding,
            "schema_data": bytes(schema.data),
        }
        note = {"hil.note": frames.base_note} if frames.base_note else {}
        self.tf = channels.add(TF_TOPIC, schema.name, {}, note, **protobuf)
        self.tf_static = channels.add(TF_STATIC_TOPIC, schema.name, {}, {}, **protobuf)
        text = {"type": "object", "properties": {"data": {"type": "string"}}}
        self.description = channels.add(DESCRIPTION_TOPIC, DESCRIPTION_SCHEMA, text)
        self._description = encode({"data": robot.viewer_urdf})
        self._next_static_s = 0.0

    def messages(self, sample: TickSample, log_time_ns: int) -> list[ViewMessage]:
        """This tick's messages (none on a tick the view skips or whose angles are not read)."""
        if sample.tick % self.every_ticks:
            return []
        transforms = self.frames.at(sample.joints["link_angle_rad"], sample.sensors)
        if transforms is None:
            return []
        out = [ViewMessage(self.tf, sample.time_s, self._encode(transforms, log_time_ns))]
        if sample.time_s >= self._next_static_s:
            self._next_static_s = sample.time_s + STATIC_EVERY_S
            static = self._encode(self.frames.static_transforms, log_time_ns)
            out.append(ViewMessage(self.tf_static, sample.time_s, static))
            out.append(ViewMessage(self.description, sample.time_s, self._description))
        return out

    def _encode(self, transforms: Sequence[FrameTransform], time_ns: int) -> bytes:
        fm = self._fm
        seconds, nanoseconds = divmod(int(time_ns), 1_000_000_000)
        stamp = fm.Timestamp(sec=seconds, nsec=nanoseconds)
        return fm.FrameTransforms(
            transforms=[
                fm.FrameTransform(
                    timestamp=stamp,
                    parent_frame_id=t.parent,
                    child_frame_id=t.child,
                    translation=fm.Vector3(
                        x=t.translation[0], y=t.translation[1], z=t.translation[2]
                    ),
                    rotation=fm.Quaternion(
                        x=t.rotation[0], y=t.rotation[1], z=t.rotation[2], w=t.rotation[3]
                    ),
                )  # fmt: skip
                for t in transforms
            ]
        ).encode()
