"""A run as a ROS 2 bag: one MCAP file in ROS 2's own encoding (profile "ros2", messages CDR,
schemas "ros2msg" as rosbag2 writes them: hil/output/ros2_messages.py), which `ros2 bag info`
and `ros2 bag play` read (rosbag2's mcap storage; Humble: add `-s mcap`), and Foxglove too.

Made from a finished run directory (`hil export ros2 RUN_DIR`, hil/output/ros2_export.py) or
while the run
goes (`hil run --ros2`: hil/output/views.py, fed the run log's messages in the log writer's
process),
the same messages either way. Every message is stamped with the run's time: the run's start
(meta.json "started", local time, to the second) plus the tick's time_s; a message's log time
is its stamp.

    topic              type                          per    what (SI)
    /joint_states      sensor_msgs/msg/JointState    tick   link side: position = link angle
                                                            [rad], effort = the gear's torque
                                                            K (motor - link) [N m], K the
                                                            controller's [model] figure
    /motor_states      sensor_msgs/msg/JointState    tick   motor side: position = motor angle
                                                            [rad], velocity [rad/s]
    /<sensor>/wrench   geometry_msgs/msg/WrenchStamped tick each force sensor (see
                                                            hil/output/robot_description.py)
    /tf                tf2_msgs/msg/TFMessage        tick   the moving joints' transforms (and
                                                            world -> base_link on the humanoid:
                                                            leg odometry, not measured)
    /tf_static         tf2_msgs/msg/TFMessage        once   every other joint's (latched)
    /robot_description std_msgs/msg/String           once   the URDF, latched as
                                                            robot_state_publisher offers it
    /hil/run_meta      std_msgs/msg/String           once   meta.json (JSON, latched)
    /hil/events        std_msgs/msg/String           event  an events.jsonl line (JSON)
    /rosout            rcl_interfaces/msg/Log        event  the same for ROS tools (name "hil")
    /hil/run_summary   std_msgs/msg/String           once   summary.json (JSON), at the end

Joint names are the log's ([[joint]] names). A value the tick did not read is NaN, as in
log.csv. /tf is left out on a tick whose link angles are not all read. Each channel's metadata
holds its QoS ("offered_qos_profiles", rosbag2's YAML of Jazzy) and, where a value needs it,
a "hil.note". The run's meta and summary are also MCAP Metadata records, as in run.mcap.

A crash keeps what was handed over: chunks of CHUNK_SIZE_BYTES reach the disk as they fill,
and the log writer finishes the file when the loop's process ends, however it ends.
"""

from __future__ import annotations

from collections.abc import Iterable
from datetime import datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

from hil.output import ros2_messages as msg
from hil.output.robot_description import RunRobot
from hil.output.robot_frames import BaseTruth, FrameTransform, robot_frames
from hil.output.strict_json import dumps, plain
from hil.output.tick_sample import TickSample

if TYPE_CHECKING:
    from collections.abc import Callable

ROS2_BAG_NAME = "run.ros2.mcap"
MISSING_EXTRA = (
    "the ROS 2 bag needs the `ros2` extra: pip install 'flexjoint-hil[ros2]' "
    "(mcap-ros2-support, for the CDR encoding)"
)
CHUNK_SIZE_BYTES = 64 * 1024
LIBRARY = "flexjoint-hil"
_FOREVER = "    sec: 9223372036\n    nsec: 854775807\n"  # rmw's infinite duration (Jazzy)
_ERROR_KINDS = frozenset({"error", "bus_failure", "start_refused", "controller_traceback"})


def ros2_support_installed() -> bool:
    """Whether the `ros2` extra (mcap-ros2-support) can be imported."""
    import importlib.util

    return importlib.util.find_spec("mcap_ros2") is not None


def offered_qos(durability: str, depth: int) -> str:
    """rosbag2's offered_qos_profiles (Jazzy's YAML): reliable, keep last `depth`."""
    return (
        f"- history: keep_last\n  depth: {depth}\n  reliability: reliable\n"
        f"  durability: {durability}\n  deadline:\n{_FOREVER}  lifespan:\n{_FOREVER}"
        f"  liveliness: automatic\n  liveliness_lease_duration:\n{_FOREVER}"
        "  avoid_ros_namespace_conventions: false\n"
    )


LATCHED = offered_qos("transient_local", 1)  # robot_state_publisher's /robot_description
STREAM = offered_qos("volatile", 10)
TF_STREAM = offered_qos("volatile", 100)  # tf2_ros's dynamic broadcaster


def run_start_ns(meta: dict[str, Any]) -> int:
    """The run's start in ns since the epoch (meta.json "started", local time); 0 without."""
    started = meta.get("started")
    if not started:
        return 0
    return int(datetime.fromisoformat(str(started)).timestamp()) * 1_000_000_000


def event_level(record: dict[str, Any]) -> int:
    """rcl_interfaces/msg/Log level of an event: a safety event (it has an action) WARN, a
    failure ERROR, anything else INFO."""
    kind = str(record.get("kind", ""))
    if kind in _ERROR_KINDS or kind.endswith("_failed"):
        return msg.LOG_ERROR
    return msg.LOG_WARN if "action" in record else msg.LOG_INFO


class Ros2Bag:
    """Writes one bag (module docstring); `close()` finishes it (safe twice)."""

    def __init__(
        self, path: Path, robot: RunRobot, meta: dict[str, Any], truth: BaseTruth | None = None
    ) -> None:
        try:
            from mcap_ros2._dynamic import serialize_dynamic  # the encoder its Writer uses
        except ImportError:
            raise ImportError(MISSING_EXTRA) from None
        from mcap.well_known import MessageEncoding, SchemaEncoding
        from mcap.writer import CompressionType, Writer

        self.path = Path(path)
        self.robot = robot
        self.frames = robot_frames(robot, truth)
        self.start_ns = run_start_ns(meta)
        self._file = open(self.path, "wb")  # noqa: SIM115 - closed in close()
        self._writer = Writer(
            self._file, chunk_size=CHUNK_SIZE_BYTES, compression=CompressionType.NONE
        )
        self._writer.start(profile="ros2", library=LIBRARY)
        self._serialize: Callable[[str, str], dict[str, Any]] = serialize_dynamic
        self._schema_encoding, self._cdr = SchemaEncoding.ROS2, MessageEncoding.CDR
        self._types: dict[str, tuple[int, Any]] = {}
        self._channels: dict[str, tuple[int, Any]] = {}
        self._sequence: dict[int, int] = {}
        self.closed = False
        self._open_channels()
        self._start(meta)

    # --- channels -----------------------------------------------------------------------------
    def _open_channels(self) -> None:
        robot = self.robot
        joints_note = "effort: the gear's torque K (motor - link angle) [N m], K of [model]"
        self._channel("/joint_states", msg.JOINT_STATE, STREAM, joints_note)
        self._channel("/motor_states", msg.JOINT_STATE, STREAM, "the motor side of each joint")
        for sensor in robot.force_sensors:
            self._channel(f"/{sensor.name}/wrench", msg.WRENCH_STAMPED, STREAM, sensor.note)
        if self.frames is not None:
            self._channel("/tf", msg.TF_MESSAGE, TF_STREAM, self.frames.base_note)
            self._channel("/tf_static", msg.TF_MESSAGE, LATCHED, "")
        if robot.viewer_urdf is not None:
            self._channel("/robot_description", msg.STRING, LATCHED, "")
        self._channel("/hil/run_meta", msg.STRING, LATCHED, "meta.json as JSON")
        self._channel("/hil/events", msg.STRING, STREAM, "an events.jsonl line as JSON")
        self._channel("/rosout", msg.LOG, offered_qos("transient_local", 1000), "")
        self._channel("/hil/run_summary", msg.STRING, LATCHED, "summary.json as JSON")

    def _channel(self, topic: str, type_name: str, qos: str, note: str) -> None:
        if type_name not in self._types:
            text = msg.schema_text(type_name)
            schema_id = self._writer.register_schema(
                type_name, self._schema_encoding, text.encode()
            )
            self._types[type_name] = (schema_id, self._serialize(type_name, text)[type_name])
        schema_id, encoder = self._types[type_name]
        metadata = {"offered_qos_profiles": qos, **({"hil.note": note} if note else {})}
        channel_id = self._writer.register_channel(topic, self._cdr, schema_id, metadata)
        self._channels[topic] = (channel_id, encoder)
        self._sequence[channel_id] = 0

    def _write(self, topic: str, time_ns: int, message: dict[str, Any]) -> None:
        channel_id, encoder = self._channels[topic]
        sequence = self._sequence[channel_id]
        self._sequence[channel_id] = sequence + 1
        self._writer.add_message(channel_id, time_ns, encoder(message), time_ns, sequence)

    def _string(self, topic: str, time_ns: int, text: str) -> None:
        self._write(topic, time_ns, {"data": text})

    # --- content ------------------------------------------------------------------------------
    def _start(self, meta: dict[str, Any]) -> None:
        t0 = self.start_ns
        if self.robot.viewer_urdf is not None:
            self._string("/robot_description", t0, self.robot.viewer_urdf)
        if self.frames is not None:
            self._write("/tf_static", t0, _tf_message(self.frames.static_transforms, t0))
        self._string("/hil/run_meta", t0, dumps(meta))
        self._writer.add_metadata("run_meta", {str(k): dumps(v) for k, v in meta.items()})

    def tick(self, sample: TickSample) -> None:
        """One log.csv row's messages."""
        t = self.stamp_ns(sample.time_s)
        robot, joints = self.robot, sample.joints
        names = list(robot.joint_names)
        link, deflection = joints["link_angle_rad"], joints["deflection_rad"]
        effort = -robot.gear_stiffness_nm_per_rad * deflection
        self._write(
            "/joint_states",
            t,
            {"header": msg.header(t), "name": names, "position": link.tolist(),
             "velocity": [], "effort": effort.tolist()},
        )  # fmt: skip
        self._write(
            "/motor_states",
            t,
            {"header": msg.header(t), "name": names,
             "position": joints["motor_angle_rad"].tolist(),
             "velocity": joints["motor_velocity_rad_s"].tolist(), "effort": []},
        )  # fmt: skip
        for sensor in robot.force_sensors:
            values = [sample.sensors[c] if c else 0.0 for c in sensor.columns]
            wrench = {
                "force": dict(zip("xyz", values[:3], strict=True)),
                "torque": dict(zip("xyz", values[3:], strict=True)),
            }
            self._write(
                f"/{sensor.name}/wrench", t, {"header": msg.header(t, sensor.frame_id), **{
                    "wrench": wrench}},
            )  # fmt: skip
        if self.frames is not None:
            transforms = self.frames.at(link, sample.sensors, sample.time_s)
            if transforms is not None:
                self._write("/tf", t, _tf_message(transforms, t))

    def event(self, record: dict[str, Any]) -> None:
        """One events.jsonl record."""
        t = self.stamp_ns(float(record.get("time_s") or 0.0))
        self._string("/hil/events", t, dumps(record))
        text = f"{record.get('kind', '')}: {record.get('message', '')}"
        log = {"stamp": msg.stamp(t), "level": event_level(record), "name": "hil", "msg": text,
               "file": "", "function": "", "line": 0}  # fmt: skip
        self._write("/rosout", t, log)

    def summary(self, summary: dict[str, Any], time_s: float) -> None:
        """summary.json, the bag's last message."""
        self._string("/hil/run_summary", self.stamp_ns(time_s), dumps(summary))
        self._writer.add_metadata(
            "run_summary", {str(k): dumps(v) for k, v in plain(summary).items()}
        )

    def stamp_ns(self, time_s: float) -> int:
        return self.start_ns + round(time_s * 1e9)

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        from hil.output.mcap_log import finish

        finish(self._writer, self._file)


def _tf_message(transforms: Iterable[FrameTransform], time_ns: int) -> dict[str, Any]:
    return {
        "transforms": [
            {
                "header": msg.header(time_ns, t.parent),
                "child_frame_id": t.child,
                "transform": {
                    "translation": dict(zip("xyz", t.translation, strict=True)),
                    "rotation": dict(zip("xyzw", t.rotation, strict=True)),
                },
            }
            for t in transforms
        ]
    }
