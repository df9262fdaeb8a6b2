"""`hil run --live`: the Foxglove WebSocket server on loopback, a real WebSocket client
subscribed to the run's channels while the in-process loop runs, and publishing that does not
wait for a client that stopped reading."""

from __future__ import annotations

import csv
import json
import struct
import threading
import time
from pathlib import Path

import pytest
from websockets.sync.client import connect

from hil.config import load_config
from hil.output.channels import ChannelSet, encode
from hil.output.live import LivePublisher
from hil.output.runlog import PER_JOINT_COLUMNS
from tests.support.rig import run_in_process

pytestmark = pytest.mark.timeout(60)
SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]
MESSAGE_DATA = 0x01  # Foxglove WebSocket protocol: binary opcode of a message


def _listening_addresses(port: int) -> set[str]:
    """Local addresses with a socket listening on `port` (Linux /proc/net/tcp, tcp6)."""
    found = set()
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        for line in Path(table).read_text().splitlines()[1:]:
            local, state = line.split()[1], line.split()[3]
            address, _, hex_port = local.partition(":")
            if int(hex_port, 16) == port and state == "0A":  # 0A: LISTEN
                found.add(address)
    return found


class Subscriber(threading.Thread):
    """Subscribes to every channel the server advertises; collects (topic, payload)."""

    def __init__(self, url: str) -> None:
        super().__init__(daemon=True)
        self.url = url
        self.received: list[tuple[str, dict | bytes]] = []
        self.subscribed = threading.Event()
        self.done = threading.Event()

    def run(self) -> None:
        topics: dict[int, str] = {}
        encodings: dict[int, str] = {}
        with connect(self.url, subprotocols=SUBPROTOCOLS) as ws:
            while not self.done.is_set():
                try:
                    frame = ws.recv(timeout=0.05)
                except TimeoutError:
                    continue
                if isinstance(frame, str):
                    message = json.loads(frame)
                    if message["op"] == "advertise":
                        subscriptions = [
                            {"id": c["id"], "channelId": c["id"]} for c in message["channels"]
                        ]
                        topics.update({c["id"]: c["topic"] for c in message["channels"]})
                        encodings.update({c["id"]: c["encoding"] for c in message["channels"]})
                        ws.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))
                        if len(topics) >= len(ChannelSet([], [], []).channels):
                            self.subscribed.set()
                elif frame[0] == MESSAGE_DATA:
                    subscription, _log_time = struct.unpack_from("<IQ", frame, 1)
                    payload = frame[13:]
                    if encodings[subscription] == "json":  # (the 3D view's /tf: protobuf)
                        payload = json.loads(payload)
                    self.received.append((topics[subscription], payload))


def test_the_server_listens_on_loopback_only_by_default() -> None:
    publisher = LivePublisher(port=0)
    try:
        assert publisher.url == f"ws://127.0.0.1:{publisher.port}"
        assert _listening_addresses(publisher.port) == {"0100007F"}  # 127.0.0.1
    finally:
        publisher.close()


class WaitingForTheClient(LivePublisher):
    """The lock-step run waits, at its first tick, until the client has subscribed (a
    person opening Foxglove takes seconds; the in-process run would be over by then)."""

    def __init__(self, subscriber_ready: threading.Event) -> None:
        super().__init__(port=0)
        self.ready = subscriber_ready

    def message(self, channel_id: int, log_time_ns: int, data: bytes) -> None:
        if not self.ready.is_set():
            assert self.ready.wait(timeout=10), "the client did not subscribe"
            time.sleep(0.2)  # the server has taken the subscription
        super().message(channel_id, log_time_ns, data)


def test_a_websocket_client_receives_the_runs_channels_live(tmp_path: Path) -> None:
    ready = threading.Event()
    publisher = WaitingForTheClient(ready)
    subscriber = Subscriber(publisher.url)
    subscriber.subscribed = ready
    subscriber.start()
    try:
        result, run = run_in_process(
            load_config(), "impact", "gc", tmp_path, duration_s=1.0, sinks=(publisher,)
        )
        time.sleep(0.3)  # the last messages on their way
    finally:
        subscriber.done.set()
        subscriber.join(timeout=5)
        publisher.close()
    assert result.ok and subscriber.subscribed.is_set()
    joints = [payload for topic, payload in subscriber.received if topic == "/joints"]
    rows = {int(r["tick"]): r for r in csv.DictReader((tmp_path / "log.csv").open())}
    assert [j["tick"] for j in joints] == sorted(rows)  # every tick, in order
    for joint in joints:
        row = rows[joint["tick"]]
        assert float(row["link_angle_rad"]) == pytest.approx(joint["link_angle_rad"][0], abs=1e-9)
    topics = {topic for topic, _ in subscriber.received}
    assert {"/joints", "/loop", "/timing", "/run/summary"} <= topics
    assert {"/tf", "/tf_static", "/robot_description"} <= topics  # the robot in 3D


@pytest.mark.timing
def test_publishing_does_not_wait_for_a_client_that_stopped_reading() -> None:
    publisher = LivePublisher(port=0)
    channels = ChannelSet(["a", "b"], PER_JOINT_COLUMNS, ["contact_force_n"])
    for channel in channels.channels:
        publisher.add_channel(channel)
    data = encode({"tick": 1, "time_s": 0.0, **{c: [0.123456789, -1.5] for c in PER_JOINT_COLUMNS}})
    try:
        with connect(publisher.url, subprotocols=SUBPROTOCOLS) as ws:
            advertise = json.loads(ws.recv(timeout=2) and ws.recv(timeout=2))
            ids = [c["id"] for c in advertise["channels"] if c["topic"] == "/joints"]
            ws.send(
                json.dumps({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": ids[0]}]})
            )
            time.sleep(0.2)
            durations = []
            for k in range(20_000):  # ~10 MB: far beyond any socket buffer; nobody reads
                started = time.perf_counter()
                publisher.message(channels.joints.id, k, data)
                durations.append(time.perf_counter() - started)
    finally:
        publisher.close()
    durations.sort()
    median, worst = durations[len(durations) // 2], durations[-1]
    print(f"live publish per message: median {median * 1e6:.1f} us, max {worst * 1e6:.1f} us")
    assert median < 50e-6
    # a blocked send would never return; what remains is the shared machine's scheduling
    assert worst < 0.05
