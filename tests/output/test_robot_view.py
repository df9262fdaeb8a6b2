"""The robot in 3D in run.mcap: the robot's frames on /tf and /tf_static in Foxglove's
foxglove.FrameTransforms, decoded here with the schema the installed foxglove-sdk ships (its
FileDescriptorSet, through google.protobuf), and the URDF on /robot_description; each tick's
transforms the same as the ROS 2 bag's (checked against the URDF and log.csv in
test_ros2_bag.py); the run log's own channels as before, so a file opens as it did."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import foxglove.messages as fm
import pytest
from google.protobuf import descriptor_pb2, message_factory
from mcap.reader import make_reader

from hil.output.channels import ChannelSet
from hil.output.robot_view import STATIC_EVERY_S
from hil.output.rundir import load_run
from hil.output.runlog import DEFAULT_SENSOR_COLUMNS, PER_JOINT_COLUMNS

pytest.importorskip("mcap_ros2")
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore

LOG_TOPICS = ("/joints", "/loop", "/timing", "/events", "/run/meta", "/run/summary")


def _frame_transforms_class() -> type:
    """foxglove.FrameTransforms from the SDK's own schema (a protobuf FileDescriptorSet)."""
    schema = fm.FrameTransforms.get_schema()
    files = descriptor_pb2.FileDescriptorSet.FromString(bytes(schema.data)).file
    return message_factory.GetMessages(files)["foxglove.FrameTransforms"]


def _run_mcap(run_dir: Path) -> tuple[dict, dict[str, list]]:
    with open(run_dir / "run.mcap", "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        channels = {c.topic: (c, summary.schemas[c.schema_id]) for c in summary.channels.values()}
        messages: dict[str, list] = {topic: [] for topic in channels}
        for _, channel, message in reader.iter_messages():
            messages[channel.topic].append(message)
    return channels, messages


def _tuples(transforms: object) -> list[tuple]:
    return [
        (t.parent_frame_id, t.child_frame_id, t.translation.x, t.translation.y, t.translation.z,
         t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w)
        for t in transforms  # type: ignore[attr-defined]
    ]  # fmt: skip


def _bag_tf(bag: Path, topic: str) -> list[list[tuple]]:
    store = get_typestore(Stores.ROS2_JAZZY)
    found = []
    with Reader(bag) as reader:
        for connection, _, raw in reader.messages():
            if connection.topic == topic:
                message = store.deserialize_cdr(raw, connection.msgtype)
                found.append(
                    [
                        (t.header.frame_id, t.child_frame_id, *(
                            getattr(t.transform.translation, a) for a in "xyz"), *(
                            getattr(t.transform.rotation, a) for a in "xyzw"))
                        for t in message.transforms
                    ]
                )  # fmt: skip
    return found


def _check_log_channels_unchanged(run_dir: Path, channels: dict) -> None:
    """The run log's six channels: the schemas and encodings a ChannelSet of this run makes,
    whatever else the file holds."""
    run = load_run(run_dir)
    names = run.joint_names if run.joint_names != ("",) else ("testbed",)
    sensors = [c for c in run.columns if c.endswith(("_n", "_nm")) and "[" not in c]
    expected = ChannelSet(names, PER_JOINT_COLUMNS, sensors or DEFAULT_SENSOR_COLUMNS)
    for channel in expected.channels:
        written, schema = channels[channel.topic]
        assert (written.message_encoding, schema.encoding) == ("json", "jsonschema")
        assert (schema.name, schema.data) == (channel.schema_name, channel.schema_bytes)
    assert [c for c in channels if c in LOG_TOPICS] == list(LOG_TOPICS)


def _check_view(run_dir: Path) -> dict[str, list]:
    channels, messages = _run_mcap(run_dir)
    _check_log_channels_unchanged(run_dir, channels)
    frame_transforms = _frame_transforms_class()
    for topic in ("/tf", "/tf_static"):
        channel, schema = channels[topic]
        assert (channel.message_encoding, schema.encoding) == ("protobuf", "protobuf")
        assert schema.name == "foxglove.FrameTransforms"
        assert schema.data == bytes(fm.FrameTransforms.get_schema().data)
    decoded = {
        topic: [frame_transforms.FromString(m.data) for m in messages[topic]]
        for topic in ("/tf", "/tf_static")
    }
    assert len(decoded["/tf"]) == len(messages["/joints"])  # a transform set every tick
    duration_s = load_run(run_dir).time_s[-1]
    assert len(decoded["/tf_static"]) == int(duration_s // STATIC_EVERY_S) + 1
    for m, joints in zip(decoded["/tf"], messages["/joints"], strict=True):
        stamp = m.transforms[0].timestamp
        assert stamp.seconds * 10**9 + stamp.nanos == joints.log_time  # the tick's own time
    channel, schema = channels["/robot_description"]
    assert schema.name == "std_msgs/msg/String"
    descriptions = {json.loads(m.data)["data"] for m in messages["/robot_description"]}
    (urdf,) = descriptions
    assert ET.fromstring(urdf).tag == "robot"
    return decoded


def test_a_walks_run_mcap_carries_the_robots_frames_and_description(walk_run: Path) -> None:
    decoded = _check_view(walk_run)
    # the joints' frames as the bag has them; the base is the leg odometry here (run.mcap is
    # written during the run), the emulator's truth in the finished run's bag
    bag_tf = _bag_tf(walk_run / "run.ros2.mcap", "/tf")
    view_tf = [_tuples(m.transforms) for m in decoded["/tf"]]
    assert [tf[1:] for tf in view_tf] == [tf[1:] for tf in bag_tf]
    assert (
        [tf[0][1] for tf in view_tf] == [tf[0][1] for tf in bag_tf] == ["base_link"] * len(bag_tf)
    )
    odometry_error = [abs(v[0][2] - b[0][2]) for v, b in zip(view_tf, bag_tf, strict=True)]
    assert max(odometry_error) < 0.01  # (tests/output/test_base_odometry.py: within 1 cm)
    (bag_static,) = _bag_tf(walk_run / "run.ros2.mcap", "/tf_static")
    assert _tuples(decoded["/tf_static"][0].transforms) == bag_static
    base = decoded["/tf"][0].transforms[0]
    assert (base.parent_frame_id, base.child_frame_id) == ("world", "base_link")
    assert 0.8 < base.translation.z < 0.95  # the pelvis above the floor, standing


def test_a_testbed_run_mcap_carries_its_link(testbed_run: Path) -> None:
    decoded = _check_view(testbed_run)
    assert {t.child_frame_id for m in decoded["/tf"] for t in m.transforms} == {"link"}
    statics = {t.child_frame_id for t in decoded["/tf_static"][0].transforms}
    assert statics == {"base_link", "load"}
