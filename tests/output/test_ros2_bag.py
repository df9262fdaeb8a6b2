"""The ROS 2 bag of a run, checked by an independent reader: `rosbags` (a second, pure-Python
ROS 2 implementation) reads the bag `hil export ros2` wrote, deserialises every message with
its own type store of ROS 2 Jazzy (not with the bag's schemas), and finds

- the topics, types, counts, serialisation format and QoS that `ros2 bag info` prints;
- each schema's definition equal to Jazzy's own definition of the type (field by field);
- every JointState, wrench and transform equal to log.csv's values at every tick (the
  transforms against the URDF's own joint origins and axes, read here with ElementTree: a
  revolute joint's transform is its origin turned by the logged link angle about its axis);
- the URDF on /robot_description, latched, its every link in the transform tree; the events,
  the meta and the summary as the run directory holds them.

A testbed run and a short walk of DYROS-JET; the walk's bag as `hil run --ros2` wrote it in
the log writer's process holds the same messages as the export; a loop killed outright leaves
a finished bag with every tick it handed over.
"""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import textwrap
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mcap_ros2")
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from hil.cli import main
from hil.output.ros2_bag import ROS2_BAG_NAME, run_start_ns
from hil.output.rundir import load_run

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
PER_TICK = ("/joint_states", "/motor_states", "/tf")
ONCE = ("/tf_static", "/robot_description", "/hil/run_meta", "/hil/run_summary")


def _export(run_dir: Path) -> Path:
    bag = run_dir.parent / f"{run_dir.name}-exported.mcap"
    bag.unlink(missing_ok=True)
    assert main(["export", "ros2", str(run_dir), "--out", str(bag)]) == 0
    return bag


def _read(bag: Path) -> tuple[dict, dict[str, list]]:
    """The connections by topic, and every message deserialised with Jazzy's type store."""
    with Reader(bag) as reader:
        connections = {c.topic: c for c in reader.connections}
        messages: dict[str, list] = {topic: [] for topic in connections}
        for connection, timestamp, raw in reader.messages():
            message = TYPESTORE.deserialize_cdr(raw, connection.msgtype)
            messages[connection.topic].append((timestamp, message))
        assert reader.message_count == sum(len(m) for m in messages.values())
    return connections, messages


def _same_values(got: np.ndarray, expected: np.ndarray) -> bool:
    """Equal as floats, NaN where the log has nan."""
    return bool(np.array_equal(np.asarray(got, float), np.asarray(expected, float), equal_nan=True))


def _normalised(fielddefs: tuple) -> tuple:
    """A type's (constants, fields); a `byte` constant is the `uint8` rosbags' store says."""
    constants, fields = fielddefs
    return ([(n, "uint8" if t == "byte" else t, v) for n, t, v in constants], fields)


def _check_info(connections: dict, messages: dict, ticks: int, events: int) -> None:
    """What `ros2 bag info` prints: per topic its type, count and serialisation format."""
    for topic in PER_TICK:
        assert connections[topic].msgcount == len(messages[topic]) == ticks, topic
    for topic in ONCE:
        assert connections[topic].msgcount == 1, topic
    assert connections["/hil/events"].msgcount == connections["/rosout"].msgcount == events
    assert {c.ext.serialization_format for c in connections.values()} == {"cdr"}
    expected = {
        "/joint_states": "sensor_msgs/msg/JointState",
        "/motor_states": "sensor_msgs/msg/JointState",
        "/tf": "tf2_msgs/msg/TFMessage",
        "/tf_static": "tf2_msgs/msg/TFMessage",
        "/robot_description": "std_msgs/msg/String",
        "/rosout": "rcl_interfaces/msg/Log",
    }
    assert {t: connections[t].msgtype for t in expected} == expected
    for topic in ("/robot_description", "/tf_static"):
        (qos,) = connections[topic].ext.offered_qos_profiles
        assert (qos.durability.name, qos.depth) == ("TRANSIENT_LOCAL", 1), topic


def _check_definitions(connections: dict) -> None:
    """Each schema, parsed by rosbags, is Jazzy's definition of its type and of every type it
    uses."""
    for connection in connections.values():
        assert connection.msgdef.format.name == "MSG"
        types = get_types_from_msg(connection.msgdef.data, connection.msgtype)
        assert connection.msgtype in types
        for name, fielddefs in types.items():
            assert _normalised(fielddefs) == _normalised(TYPESTORE.fielddefs[name]), name


def _joint_transforms(urdf: str) -> dict[str, tuple[str, str, np.ndarray, np.ndarray, str]]:
    """child link -> (joint, parent, origin xyz, axis, type) from the URDF text."""
    found = {}
    for joint in ET.fromstring(urdf).findall("joint"):
        origin = joint.find("origin")
        axis = joint.find("axis")
        xyz = np.fromstring(origin.get("xyz", "0 0 0") if origin is not None else "0 0 0", sep=" ")
        a = np.fromstring(axis.get("xyz") if axis is not None else "1 0 0", sep=" ")
        child, parent = joint.find("child").get("link"), joint.find("parent").get("link")
        found[child] = (joint.get("name"), parent, xyz, a, joint.get("type"))
    return found


def _check_frames(run_dir: Path, messages: dict) -> None:
    """Every moving joint's transform: the URDF's origin, turned by the log's link angle about
    the joint's axis (the URDF's rpy is zero on every moving joint of both robots); every link
    of the URDF in the tree of /tf and /tf_static."""
    run = load_run(run_dir)
    ((_, description),) = messages["/robot_description"]
    joints = _joint_transforms(description.data)
    ((_, static),) = messages["/tf_static"]
    tree = {t.child_frame_id: t.header.frame_id for t in static.transforms}
    names = run.joint_names if run.joint_names != ("",) else ("testbed",)
    link = np.array(run.per_joint("link_angle_rad"))
    for tick, (_, message) in enumerate(messages["/tf"]):
        for transform in message.transforms:
            child = transform.child_frame_id
            tree[child] = transform.header.frame_id
            joint, parent, xyz, axis, kind = joints[child]
            assert transform.header.frame_id == parent
            if kind == "floating":
                continue
            t, r = transform.transform.translation, transform.transform.rotation
            assert np.allclose([t.x, t.y, t.z], xyz, atol=1e-12), joint
            angle = link[names.index(joint), tick]
            half = angle / 2
            expected = np.array([*(math.sin(half) * axis / np.linalg.norm(axis)), math.cos(half)])
            expected *= np.sign(expected[3]) or 1.0
            assert np.allclose([r.x, r.y, r.z, r.w], expected, atol=1e-12), (joint, tick)
    links = {link.get("name") for link in ET.fromstring(description.data).findall("link")}
    for name in links - {"world"}:
        frame, hops = name, 0
        while frame != "world" and hops < 100:
            frame, hops = tree[frame], hops + 1
        assert frame == "world", name


def _check_values(run_dir: Path, messages: dict) -> None:
    """/joint_states, /motor_states and the wrenches against log.csv, tick by tick, stamped with
    the run's time."""
    run = load_run(run_dir)
    start = run_start_ns(run.meta)
    assert start > 0
    k = np.array([2000.0] * len(run.per_joint("link_angle_rad")))  # [model] K of both robots
    columns = {
        name: np.array(run.per_joint(name))
        for name in ("link_angle_rad", "motor_angle_rad", "motor_velocity_rad_s", "deflection_rad")
    }
    for tick, ((stamp, joints), (_, motors)) in enumerate(
        zip(messages["/joint_states"], messages["/motor_states"], strict=True)
    ):
        expected_ns = start + round(run.time_s[tick] * 1e9)
        assert stamp == expected_ns
        assert joints.header.stamp.sec * 10**9 + joints.header.stamp.nanosec == expected_ns
        assert _same_values(joints.position, columns["link_angle_rad"][:, tick])
        assert _same_values(joints.effort, -k * columns["deflection_rad"][:, tick])
        assert _same_values(motors.position, columns["motor_angle_rad"][:, tick])
        assert _same_values(motors.velocity, columns["motor_velocity_rad_s"][:, tick])
    wrench_topics = [t for t in messages if t.endswith("/wrench")]
    assert wrench_topics
    for topic in wrench_topics:
        name = topic.split("/")[1]
        for tick, (_, message) in enumerate(messages[topic]):
            w = message.wrench
            got = [w.force.x, w.force.y, w.force.z, w.torque.x, w.torque.y, w.torque.z]
            if name == "contact":
                expected = [0, 0, run.columns["contact_force_n"][tick], 0, 0, 0]
            else:
                keys = ("fx_n", "fy_n", "fz_n", "mx_nm", "my_nm", "mz_nm")
                expected = [run.columns[f"{name}_{key}"][tick] for key in keys]
            assert _same_values(got, expected), (topic, tick)


def _check_documents(run_dir: Path, messages: dict) -> None:
    ((_, description),) = messages["/robot_description"]
    assert ET.fromstring(description.data).tag == "robot"
    events = [json.loads(line) for line in (run_dir / "events.jsonl").read_text().splitlines()]
    assert [json.loads(m.data) for _, m in messages["/hil/events"]] == events
    logged = [f"{e['kind']}: {e['message']}" for e in events]
    assert [m.msg for _, m in messages["/rosout"]] == logged
    ((_, meta),) = messages["/hil/run_meta"]
    assert json.loads(meta.data) == json.loads((run_dir / "meta.json").read_text())
    ((_, summary),) = messages["/hil/run_summary"]
    assert json.loads(summary.data) == json.loads((run_dir / "summary.json").read_text())


def _check_bag(run_dir: Path, bag: Path) -> dict:
    connections, messages = _read(bag)
    run = load_run(run_dir)
    _check_info(connections, messages, len(run.time_s), len(run.events))
    _check_definitions(connections)
    _check_values(run_dir, messages)
    _check_frames(run_dir, messages)
    _check_documents(run_dir, messages)
    return messages


def test_a_testbed_run_exported_is_read_back_by_rosbags(testbed_run: Path) -> None:
    messages = _check_bag(testbed_run, _export(testbed_run))
    assert max(m.wrench.force.z for _, m in messages["/contact/wrench"]) > 1.0  # the block


def test_a_walk_exported_is_read_back_by_rosbags(walk_run: Path) -> None:
    messages = _check_bag(walk_run, _export(walk_run))
    ((_, static),) = messages["/tf_static"]
    assert len(static.transforms) == 16  # the waist and the arms, locked
    assert all(len(m.transforms) == 13 for _, m in messages["/tf"])  # base + 12 leg joints


def _raw(bag: Path) -> dict[str, list[tuple[int, int, bytes]]]:
    from mcap.reader import make_reader

    found: dict[str, list[tuple[int, int, bytes]]] = {}
    with open(bag, "rb") as f:
        for _, channel, message in make_reader(f).iter_messages(log_time_order=False):
            found.setdefault(channel.topic, []).append(
                (message.log_time, message.sequence, message.data)
            )
    return found


def test_hil_run_ros2_leaves_the_bag_the_export_makes(walk_run: Path) -> None:
    """Byte for byte, /tf too: the bag written during the run has the leg odometry for the
    humanoid's base; once the emulator has stopped, the run's bag is made again with its truth
    (tests/output/test_emulator_truth.py checks that base against the truth)."""
    written = walk_run / ROS2_BAG_NAME
    _check_bag(walk_run, written)
    assert _raw(written) == _raw(_export(walk_run))
    assert not list(walk_run.glob(".*with-truth"))


def test_the_bag_written_during_a_run_is_the_one_the_export_makes(tmp_path: Path) -> None:
    """The log writer's own bag (kept when there is no emulator truth: in process, on
    hardware, or if the run ends before it is made again), byte for byte the export's."""
    from hil.config import load_config
    from hil.robots import get_experiment
    from hil.session import Session, Setup
    from hil.vocabulary import ControllerChoice

    config = load_config(robot="dyros-jet")
    session = Session(config, Setup.IN_PROCESS, out_root=tmp_path, plots=False, quiet=True)
    session.ros2 = True
    result = session.run_one(
        get_experiment("walk-slow"), ControllerChoice("gc"), duration_s=2.0, print_result=False
    )
    assert result.termination.ran_its_course, result.ending
    written = result.out_dir / ROS2_BAG_NAME
    assert not (result.out_dir / "emulator_truth.csv").exists()
    _check_bag(result.out_dir, written)
    during, after = _raw(written), _raw(_export(result.out_dir))
    assert set(during) >= set(PER_TICK) and during == after


_KILLED_LOOP = textwrap.dedent(
    """
    import sys
    from datetime import datetime
    from pathlib import Path
    from hil.config import load_config
    from hil.experiments import IMPACT
    from hil.loop.clock import LockstepClock
    from hil.loop.request import RunRequest
    from hil.loop.runner import run_experiment
    from hil.vocabulary import ControllerChoice
    from hil.wiring.in_process import in_process_bus

    config = load_config()
    meta = {"config": config.record(), "started": datetime.now().isoformat(timespec="seconds"),
            "ros2_bag": "run.ros2.mcap"}
    request = RunRequest(IMPACT, ControllerChoice("pid"), Path(sys.argv[1]), duration_s=60)
    bus = in_process_bus(config, IMPACT)
    run_experiment(config, request, bus, LockstepClock(config.loop.period_s), meta)
    """
)


def test_a_loop_killed_outright_leaves_a_finished_bag_with_every_tick_handed_over(
    tmp_path: Path,
) -> None:
    """The log writer finishes the bag when the loop's process ends, however it ends: the bag
    holds a JointState for every row of log.csv (which holds every row handed over:
    tests/hil/test_log_process.py)."""
    out = tmp_path / "run"
    loop = subprocess.Popen(
        [sys.executable, "-c", _KILLED_LOOP, str(out)], cwd=Path(__file__).resolve().parents[2]
    )
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and len(_lines(out / "log.csv")) < 300:
            time.sleep(0.05)
        os.kill(loop.pid, signal.SIGKILL)
    finally:
        loop.wait(timeout=30)
    bag = out / ROS2_BAG_NAME
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and bag.read_bytes()[-8:] != b"\x89MCAP0\r\n":
        time.sleep(0.1)  # the writer writes what it holds, then finishes the bag
    _, messages = _read(bag)  # rosbags reads its index: a finished file
    run = load_run(out)
    assert 300 <= len(run.time_s) < 60 * 200  # killed mid-run
    assert len(messages["/joint_states"]) == len(run.time_s)
    link = np.array(run.per_joint("link_angle_rad"))[0]
    assert _same_values([m.position[0] for _, m in messages["/joint_states"]], link)


def _lines(path: Path) -> list[str]:
    return path.read_text().splitlines() if path.exists() else []


def test_without_the_ros2_extra_the_user_is_told_to_install_it(
    testbed_run: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture,
) -> None:
    import hil.output.ros2_bag as ros2_bag

    monkeypatch.setitem(sys.modules, "mcap_ros2._dynamic", None)  # import fails, as uninstalled
    monkeypatch.setattr(ros2_bag, "ros2_support_installed", lambda: False)
    out = tmp_path / "bag.mcap"
    assert main(["export", "ros2", str(testbed_run), "--out", str(out)]) == 2
    assert ros2_bag.MISSING_EXTRA in capsys.readouterr().err
    runs = tmp_path / "runs"
    assert main(["run", "contact", "--ros2", "--duration", "1", "--out", str(runs)]) == 2
    assert ros2_bag.MISSING_EXTRA in capsys.readouterr().err
    assert not list(runs.glob("*/log.csv"))  # refused before the run began
