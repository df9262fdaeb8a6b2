"""The ROS 2 message types a bag of a run holds, defined as ROS 2 defines them (the interface
packages' .msg files of Jazzy: builtin_interfaces, std_msgs, geometry_msgs, sensor_msgs,
tf2_msgs, rcl_interfaces; comments left out), and their schema text as rosbag2 writes it into an
MCAP Schema record (encoding "ros2msg"): the type's definition, then each type it uses, depth
first, each after a line of 80 '=' and "MSG: package/Type" (rosbag2_cpp's
LocalMessageDefinitionSource, whose dependencies are a sorted set).

The bag's own content is in hil/output/ros2_bag.py; the CDR encoding is mcap-ros2-support's.
"""

from __future__ import annotations

import re

TIME = "builtin_interfaces/msg/Time"
HEADER = "std_msgs/msg/Header"
STRING = "std_msgs/msg/String"
JOINT_STATE = "sensor_msgs/msg/JointState"
WRENCH_STAMPED = "geometry_msgs/msg/WrenchStamped"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
LOG = "rcl_interfaces/msg/Log"

DEFINITIONS: dict[str, str] = {
    TIME: "int32 sec\nuint32 nanosec\n",
    HEADER: "builtin_interfaces/Time stamp\nstring frame_id\n",
    STRING: "string data\n",
    JOINT_STATE: (
        "std_msgs/Header header\n\nstring[] name\nfloat64[] position\nfloat64[] velocity\n"
        "float64[] effort\n"
    ),
    "geometry_msgs/msg/Vector3": "float64 x\nfloat64 y\nfloat64 z\n",
    "geometry_msgs/msg/Quaternion": "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n",
    "geometry_msgs/msg/Wrench": "Vector3 force\nVector3 torque\n",
    WRENCH_STAMPED: "std_msgs/Header header\nWrench wrench\n",
    "geometry_msgs/msg/Transform": "Vector3 translation\nQuaternion rotation\n",
    "geometry_msgs/msg/TransformStamped": (
        "std_msgs/Header header\nstring child_frame_id\nTransform transform\n"
    ),
    TF_MESSAGE: "geometry_msgs/TransformStamped[] transforms\n",
    LOG: (
        "byte DEBUG=10\nbyte INFO=20\nbyte WARN=30\nbyte ERROR=40\nbyte FATAL=50\n\n"
        "builtin_interfaces/Time stamp\nuint8 level\nstring name\nstring msg\nstring file\n"
        "string function\nuint32 line\n"
    ),
}
LOG_INFO, LOG_WARN, LOG_ERROR = 20, 30, 40
_PRIMITIVES = frozenset(
    ("bool", "byte", "char", "float32", "float64", "string")
    + tuple(f"{sign}int{bits}" for sign in ("", "u") for bits in (8, 16, 32, 64))
)
_FIELD_TYPE = re.compile(r"(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+")
_DELIMITER = "=" * 80 + "\n"


def _full_name(short: str) -> str:
    """ "std_msgs/Header" -> "std_msgs/msg/Header"."""
    package, _, name = short.rpartition("/")
    return f"{package}/msg/{name}"


def _dependencies(type_name: str) -> list[str]:
    """The message types a definition uses, as written ("package/Type"), sorted."""
    package = type_name.split("/")[0]
    found = set()
    for match in _FIELD_TYPE.finditer(DEFINITIONS[type_name]):
        field_type = match.group(1)
        if field_type in _PRIMITIVES:
            continue
        found.add(field_type if "/" in field_type else f"{package}/{field_type}")
    return sorted(found)


def schema_text(type_name: str) -> str:
    """The MCAP schema data of `type_name` as rosbag2 writes it (module docstring)."""
    seen: set[str] = set()

    def text(name: str) -> str:
        result = DEFINITIONS[name]
        for dependency in _dependencies(name):
            if dependency not in seen:
                seen.add(dependency)
                result += f"\n{_DELIMITER}MSG: {dependency}\n" + text(_full_name(dependency))
        return result

    return text(type_name)


def stamp(time_ns: int) -> dict[str, int]:
    """builtin_interfaces/msg/Time of a time in ns since the epoch."""
    seconds, nanoseconds = divmod(int(time_ns), 1_000_000_000)
    return {"sec": seconds, "nanosec": nanoseconds}


def header(time_ns: int, frame_id: str = "") -> dict[str, object]:
    return {"stamp": stamp(time_ns), "frame_id": frame_id}
