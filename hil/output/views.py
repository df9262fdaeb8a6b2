"""The views a run log derives from its own messages while the run goes: the robot in 3D
(hil/output/robot_view.py) in run.mcap and on the live view, and the ROS 2 bag
(hil/output/ros2_bag.py) when the run asks for one (`hil run --ros2`: meta.json's
"ros2_bag" names the file). They are made where the run log is written (the log writer's
process, or the loop's with the live view), from the same messages as run.mcap.

`attach_views` is the run log's one hook (hil/output/runlog.py): it puts a `RunViews` in front
of the log's sinks. A view that fails never takes the record with it: it says why once on
stderr and stops, the log's own channels go on.
"""

from __future__ import annotations

import json
import sys
import traceback
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from hil.output.channels import EVENTS, JOINTS, LOOP, SUMMARY, Channel, ChannelSet, MessageSink
from hil.output.robot_description import robot_of_run
from hil.output.tick_sample import VIEW_COLUMNS, TickAssembler

if TYPE_CHECKING:
    from hil.output.robot_view import RobotView
    from hil.output.ros2_bag import Ros2Bag

ROS2_BAG_KEY = "ros2_bag"  # meta.json: the bag's file name in the run directory, if asked for


class RunLogParts(Protocol):
    """What a run log shows its views (hil.output.runlog.RunLog)."""

    dir: Path
    joint_names: tuple[str, ...]
    sensor_columns: tuple[str, ...]
    channels: ChannelSet


def attach_views(
    log: RunLogParts, meta: dict[str, Any], sinks: list[MessageSink]
) -> tuple[list[MessageSink], list[MessageSink]]:
    """(the sinks the log publishes to, the views it closes when it finishes its sinks)."""
    bag_name = meta.get(ROS2_BAG_KEY)
    if not sinks and not bag_name:
        return sinks, []
    robot = _attempt("the robot's description", lambda: robot_of_run(
        meta, log.joint_names, log.sensor_columns))  # fmt: skip
    if robot is None:
        return sinks, []
    view = None
    if sinks and robot.viewer_urdf is not None:
        from hil.output.mcap_log import McapSink
        from hil.output.robot_view import LIVE_EVERY_TICKS, RobotView

        every = 1 if all(isinstance(s, McapSink) for s in sinks) else LIVE_EVERY_TICKS
        view = _attempt("the 3D view", lambda: RobotView(robot, log.channels, every))
    bag = None
    if bag_name:
        from hil.output.ros2_bag import Ros2Bag

        bag = _attempt("the ROS 2 bag", lambda: Ros2Bag(log.dir / str(bag_name), robot, meta))
    views = RunViews(sinks, view, bag, log.sensor_columns)
    return [views], [views]


def _attempt(what: str, make: Any) -> Any:
    try:
        return make()
    except Exception:  # noqa: BLE001 - a view never stops the run: said, then left out
        _say(what, "could not start")
        return None


def _say(what: str, how: str) -> None:
    print(f"hil: {what} {how} (the run's record goes on):", file=sys.stderr)
    traceback.print_exc(file=sys.stderr)


class RunViews:
    """A MessageSink in front of the log's sinks: every message goes on to them; from each
    tick (/joints, then /loop) the 3D view's messages are added and the bag's written."""

    def __init__(
        self,
        sinks: Sequence[MessageSink],
        view: RobotView | None,
        bag: Ros2Bag | None,
        sensor_columns: Sequence[str],
    ) -> None:
        self.sinks = list(sinks)
        self.view = view
        self.bag = bag
        self._assembler = TickAssembler(VIEW_COLUMNS, tuple(sensor_columns))
        self._topics: dict[int, str] = {}
        self._last_s = 0.0

    def add_channel(self, channel: Channel) -> None:
        self._topics[channel.id] = channel.topic
        for sink in self.sinks:
            sink.add_channel(channel)

    def message(self, channel_id: int, log_time_ns: int, data: bytes) -> None:
        for sink in self.sinks:
            sink.message(channel_id, log_time_ns, data)
        if self.view is None and self.bag is None:
            return
        topic = self._topics.get(channel_id)
        if topic == JOINTS:
            self._assembler.joints(data)
        elif topic == LOOP:
            self._tick(self._assembler.loop(data), log_time_ns)
        elif topic == EVENTS and self.bag is not None:
            record = json.loads(data)
            self._last_s = max(self._last_s, float(record.get("time_s") or 0.0))
            self._bag(lambda bag: bag.event(record))
        elif topic == SUMMARY and self.bag is not None:
            self._bag(lambda bag: bag.summary(json.loads(data), self._last_s))

    def _tick(self, sample: Any, log_time_ns: int) -> None:
        if sample is None:
            return
        self._last_s = max(self._last_s, sample.time_s)
        if self.view is not None:
            try:
                derived = self.view.messages(sample, log_time_ns)
            except Exception:  # noqa: BLE001 - said once, the view stops
                _say("the 3D view", f"stopped at t = {sample.time_s:g} s")
                self.view, derived = None, []
            for message in derived:
                for sink in self.sinks:
                    sink.message(message.channel.id, log_time_ns, message.data)
        self._bag(lambda bag: bag.tick(sample))

    def _bag(self, write: Any) -> None:
        if self.bag is None:
            return
        try:
            write(self.bag)
        except Exception:  # noqa: BLE001 - said once; what was written is kept
            _say("the ROS 2 bag", f"stopped at t = {self._last_s:g} s")
            self.close()
            self.bag = None

    def close(self) -> None:
        """The bag finished (the log's own sinks are the log's to close)."""
        if self.bag is not None:
            try:
                self.bag.close()
            except Exception:  # noqa: BLE001
                _say("the ROS 2 bag", "could not be finished")
