"""Emulated CiA 406 / CiA 404 nodes against an unmodified `canopen` master on python-can `virtual`.

Lock-step tests pump the nodes with a synthetic clock and feed the master's received frames to
canopen by hand (`network.notify`), so they are thread-free and deterministic. SDO tests need
canopen's blocking SDO client, so there the nodes are served from a background thread.
"""

from __future__ import annotations

import math
import struct
import time
import uuid
from collections.abc import Callable, Iterator

import can
import canopen
import numpy as np
import pytest

from sim_backend.canbus import CanSegment, ForceSensorNode, LinkEncoderNode, NodeRunner
from sim_backend.canbus.encoder_node import ENCODER_EDS_FILE
from sim_backend.canbus.force_sensor_node import FORCE_SENSOR_EDS_FILE
from sim_backend.canbus.object_store import eds_path
from sim_backend.canbus.slave import DEFAULT_BOOTUP_DELAY_S
from sim_backend.canbus.testing import serve_in_background

pytestmark = pytest.mark.timeout(30)

COUNTS_PER_REV = 983_040
NODE = 5


class LockStepWire:
    """A segment and a master bus on one virtual channel; the test owns the clock."""

    def __init__(self, nodes: list) -> None:
        channel = f"test-can-nodes-{uuid.uuid4()}"
        self.node_bus = can.Bus(interface="virtual", channel=channel)
        self.master_bus = can.Bus(interface="virtual", channel=channel)
        self.runner = NodeRunner(self.node_bus, CanSegment(nodes))
        self.network = canopen.Network(self.master_bus)  # no connect(): no Notifier thread
        self.now_s = 0.0

    def send(self, cob_id: int, data: bytes = b"") -> None:
        self.master_bus.send(can.Message(arbitration_id=cob_id, data=data, is_extended_id=False))

    def step(self, dt_s: float = 0.0) -> list[can.Message]:
        """Advance the clock, let the nodes react, return (and notify canopen of) what came back."""
        self.now_s += dt_s
        self.runner.pump(self.now_s)
        frames = []
        while (msg := self.master_bus.recv(timeout=0.0)) is not None:
            frames.append(msg)
            self.network.notify(msg.arbitration_id, msg.data, msg.timestamp)
        return frames

    def sync(self) -> list[can.Message]:
        self.network.sync.transmit()
        return self.step()

    def close(self) -> None:
        self.master_bus.shutdown()
        self.node_bus.shutdown()


@pytest.fixture
def wire_factory() -> Iterator[Callable[[list], LockStepWire]]:
    wires: list[LockStepWire] = []

    def make(nodes: list) -> LockStepWire:
        wires.append(LockStepWire(nodes))
        return wires[-1]

    yield make
    for wire in wires:
        wire.close()


@pytest.fixture
def served_master() -> Iterator[Callable[..., tuple[canopen.RemoteNode, LinkEncoderNode]]]:
    """A canopen master (with its Notifier) and nodes served from a background thread."""
    stack = []

    def make(node: LinkEncoderNode | ForceSensorNode, eds_file: str = ENCODER_EDS_FILE):
        channel = f"test-can-sdo-{uuid.uuid4()}"
        node_bus = can.Bus(interface="virtual", channel=channel)
        runner = NodeRunner(node_bus, CanSegment([node]))
        started = time.monotonic()
        background = serve_in_background(runner, lambda: time.monotonic() - started)
        background.__enter__()
        network = canopen.Network()
        network.NOTIFIER_CYCLE = 0.01
        network.connect(interface="virtual", channel=channel)
        remote = network.add_node(node.node_id, str(eds_path(eds_file)))
        stack.append((network, background, node_bus))
        return remote, node

    yield make
    for network, background, node_bus in stack:
        network.disconnect()
        background.__exit__(None, None, None)
        node_bus.shutdown()


def position_of(frames: list[can.Message], node_id: int = NODE) -> list[int]:
    return [
        struct.unpack("<i", frame.data[:4])[0]
        for frame in frames
        if frame.arbitration_id == 0x180 + node_id
    ]


def expected_counts(angle_rad: float) -> int:
    """round(angle * N / 2pi), half up, computed independently of the emulator."""
    return math.floor(angle_rad * COUNTS_PER_REV / (2.0 * math.pi) + 0.5)


def started_encoder(
    wire_factory: Callable[[list], LockStepWire], angle: list[float], **kwargs
) -> tuple[LockStepWire, LinkEncoderNode]:
    node = LinkEncoderNode(NODE, lambda: angle[0], **kwargs)
    wire = wire_factory([node])
    wire.step()  # boot-up
    wire.network.nmt.send_command(0x01)  # start all
    wire.step()
    return wire, node


# --- boot-up, NMT, heartbeat (lock-step, synthetic clock) ------------------------------------
def test_boot_up_frame_at_power_on_then_pre_operational(wire_factory) -> None:
    node = LinkEncoderNode(NODE, lambda: 0.0)
    wire = wire_factory([node])
    frames = wire.step()
    assert [(f.arbitration_id, bytes(f.data)) for f in frames] == [(0x705, b"\x00")]
    assert node.nmt_state == 0x7F
    assert wire.step(0.01) == []  # boot-up only once


def test_heartbeat_period_and_states_follow_nmt_on_the_emulator_clock(wire_factory) -> None:
    node = LinkEncoderNode(NODE, lambda: 0.0, heartbeat_ms=100)
    wire = wire_factory([node])
    remote = wire.network.add_node(NODE, str(eds_path(ENCODER_EDS_FILE)))
    seen: list[tuple[float, int]] = []
    remote.nmt.add_heartbeat_callback(lambda state: seen.append((round(wire.now_s, 6), state)))
    wire.step()  # boot-up at t = 0
    for _ in range(10):  # 0.05 s steps up to 0.5 s
        wire.step(0.05)
    assert seen == [(0.0, 0x00), (0.1, 0x7F), (0.2, 0x7F), (0.3, 0x7F), (0.4, 0x7F), (0.5, 0x7F)]
    assert remote.nmt.state == "PRE-OPERATIONAL"

    # A state change is announced at once, then the period restarts from there.
    remote.nmt.state = "OPERATIONAL"
    wire.step()
    assert seen[-1] == (0.5, 0x05) and remote.nmt.state == "OPERATIONAL"
    wire.step(0.05)
    assert seen[-1] == (0.5, 0x05)
    wire.step(0.05)
    assert seen[-1] == (0.6, 0x05)
    remote.nmt.state = "STOPPED"
    wire.step()
    assert seen[-1] == (0.6, 0x04) and node.nmt_state == 0x04
    remote.nmt.state = "PRE-OPERATIONAL"
    wire.step()
    assert seen[-1] == (0.6, 0x7F)
    remote.nmt.state = "PRE-OPERATIONAL"  # no change: no extra heartbeat
    assert wire.step() == []

    # A caller that skips whole periods gets one heartbeat, not a burst.
    count_before = len(seen)
    wire.step(1.0)
    assert len(seen) == count_before + 1


def test_heartbeat_zero_disables_it(wire_factory) -> None:
    wire = wire_factory([LinkEncoderNode(NODE, lambda: 0.0, heartbeat_ms=0)])
    assert len(wire.step()) == 1  # boot-up only
    assert wire.step(5.0) == []


def test_reset_node_and_reset_communication_send_boot_up_and_restore_defaults(
    served_master,
) -> None:
    remote, node = served_master(LinkEncoderNode(NODE, lambda: 0.0))
    remote.sdo[0x1017].raw = 20
    remote.sdo[0x6000].raw = 0x0001  # application object: survives reset communication
    remote.nmt.send_command(0x82)  # reset communication
    remote.nmt.wait_for_heartbeat(timeout=1.0)  # boot-up or the next heartbeat
    assert remote.sdo[0x1017].raw == 100
    assert remote.sdo[0x6000].raw == 0x0001
    remote.nmt.send_command(0x81)  # reset node
    remote.nmt.wait_for_heartbeat(timeout=1.0)
    assert remote.sdo[0x6000].raw == 0
    assert node.nmt_state == 0x7F


def test_nmt_command_for_another_node_is_ignored(wire_factory) -> None:
    angle = [0.0]
    wire, node = started_encoder(wire_factory, angle)
    wire.send(0x000, bytes([0x02, NODE + 1]))
    wire.step()
    assert node.nmt_state == 0x05


# --- SDO (canopen's SDO client) ----------------------------------------------------------------
def test_sdo_reads_device_type_resolution_identity_and_name(served_master) -> None:
    remote, _ = served_master(LinkEncoderNode(NODE, lambda: 0.0))
    assert remote.sdo[0x1000].raw == 0x0002_0196
    assert remote.sdo[0x1000].raw & 0xFFFF == 406
    assert remote.sdo[0x6001].raw == COUNTS_PER_REV
    assert remote.sdo[0x6501].raw == COUNTS_PER_REV
    identity = remote.sdo[0x1018]
    assert identity[0].raw == 4
    assert [identity[sub].raw for sub in (1, 2, 3, 4)] == [0, 0x406, 0x0001_0000, 0x4060_0005]
    # longer than 4 bytes: segmented upload
    assert remote.sdo[0x1008].raw.startswith("RLC2IC+MR075 CiA 406")
    assert remote.sdo[0x1001].raw == 0


def test_sdo_writes_heartbeat_time_and_operating_parameters(served_master) -> None:
    remote, node = served_master(LinkEncoderNode(NODE, lambda: 0.0))
    remote.sdo[0x1017].raw = 40
    assert remote.sdo[0x1017].raw == 40
    remote.sdo[0x6000].raw = 0x0001
    assert remote.sdo[0x6000].raw == 0x0001
    assert remote.sdo[0x6500].raw == 0x0001  # operating status mirrors it
    # also through a segmented download (forced), which canopen never uses for 2 bytes
    remote.sdo.download(0x1017, 0, struct.pack("<H", 60), force_segment=True)
    assert remote.sdo[0x1017].raw == 60
    assert node.nmt_state == 0x7F


@pytest.mark.parametrize(
    ("action", "abort_code"),
    [
        (lambda r: setattr(r.sdo[0x6001], "raw", 4096), 0x0601_0002),  # read-only
        (lambda r: setattr(r.sdo[0x1000], "raw", 1), 0x0601_0002),
        (lambda r: r.sdo.upload(0x2000, 0), 0x0602_0000),  # no such object
        (lambda r: r.sdo.upload(0x1018, 9), 0x0609_0011),  # no such sub-index
        (lambda r: setattr(r.sdo[0x1800][2], "raw", 250), 0x0609_0030),  # reserved type
        (lambda r: setattr(r.sdo[0x6000], "raw", 0x0004), 0x0609_0030),  # scaling
        (lambda r: r.sdo.download(0x1017, 0, b"\x01\x00\x00\x00"), 0x0607_0012),  # too long
        (lambda r: setattr(r.sdo[0x1800][1], "raw", 0x186), 0x0609_0030),  # valid -> valid
    ],
)
def test_sdo_abort_codes(served_master, action, abort_code: int) -> None:
    remote, _ = served_master(LinkEncoderNode(NODE, lambda: 0.0))
    with pytest.raises(canopen.SdoAbortedError) as raised:
        action(remote)
    assert raised.value.code == abort_code


def test_tpdo_cob_id_can_be_moved_while_invalid(served_master) -> None:
    remote, _ = served_master(LinkEncoderNode(NODE, lambda: 0.0))
    remote.sdo[0x1800][1].raw = 0x8000_0185
    remote.sdo[0x1800][1].raw = 0x0000_0285
    assert remote.sdo[0x1800][1].raw == 0x285


def test_no_sdo_answer_in_stopped(wire_factory) -> None:
    angle = [0.0]
    wire, node = started_encoder(wire_factory, angle)
    wire.send(0x000, bytes([0x02, NODE]))
    wire.step()
    wire.send(0x605, bytes([0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]))
    assert wire.step() == []
    wire.send(0x000, bytes([0x80, NODE]))
    wire.step()
    wire.send(0x605, bytes([0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]))
    (answer,) = wire.step()
    assert answer.arbitration_id == 0x585 and bytes(answer.data[4:]) == b"\x96\x01\x02\x00"


# --- TPDO on SYNC -----------------------------------------------------------------------------
def test_tpdo_only_in_operational(wire_factory) -> None:
    angle = [0.25]
    node = LinkEncoderNode(NODE, lambda: angle[0])
    wire = wire_factory([node])
    wire.step()
    assert position_of(wire.sync()) == []  # Pre-operational
    wire.network.nmt.send_command(0x01)
    wire.step()
    assert position_of(wire.sync()) == [expected_counts(0.25)]
    wire.network.nmt.send_command(0x02)
    wire.step()
    assert position_of(wire.sync()) == []  # Stopped
    wire.network.nmt.send_command(0x01)
    wire.step()
    assert position_of(wire.sync()) == [expected_counts(0.25)]


def test_tpdo_decoded_by_canopen_pdo_map(wire_factory) -> None:
    angle = [-0.4]
    wire, _ = started_encoder(wire_factory, angle)
    remote = wire.network.add_node(NODE, str(eds_path(ENCODER_EDS_FILE)))
    remote.tpdo.read(from_od=True)
    received: list[int] = []
    remote.tpdo[1].add_callback(lambda pdo_map: received.append(pdo_map["Position value"].raw))
    wire.sync()
    angle[0] = 0.7
    wire.sync()
    assert received == [expected_counts(-0.4), expected_counts(0.7)]


def test_position_latched_at_the_sync_instant(wire_factory) -> None:
    angle = [0.0]
    wire, _ = started_encoder(wire_factory, angle)
    positions = []
    for k in range(5):
        angle[0] = 0.01 * k
        positions += position_of(wire.sync())
    assert positions == [expected_counts(0.01 * k) for k in range(5)]


@pytest.mark.parametrize(
    "angle_rad",
    [0.0, 1e-7, 0.3, -0.3, math.pi, -math.pi / 2, 2 * math.pi, -7.5, 100.0, -2.0e-6],
)
def test_quantisation_within_half_a_count(wire_factory, angle_rad: float) -> None:
    angle = [angle_rad]
    wire, _ = started_encoder(wire_factory, angle)
    (counts,) = position_of(wire.sync())
    assert counts == expected_counts(angle_rad)
    assert abs(counts * 2.0 * math.pi / COUNTS_PER_REV - angle_rad) <= math.pi / COUNTS_PER_REV


def test_quantisation_landmarks(wire_factory) -> None:
    one_count_rad = 2.0 * math.pi / COUNTS_PER_REV
    cases = {
        2.0 * math.pi: COUNTS_PER_REV,
        -math.pi / 2: -COUNTS_PER_REV // 4,
        0.49 * one_count_rad: 0,
        0.51 * one_count_rad: 1,
        -0.51 * one_count_rad: -1,
        -0.49 * one_count_rad: 0,
    }
    angle = [0.0]
    wire, _ = started_encoder(wire_factory, angle)
    for angle_rad, counts in cases.items():
        angle[0] = angle_rad
        assert position_of(wire.sync()) == [counts], angle_rad


def test_direction_code_sequence_and_preset(served_master) -> None:
    angle = [0.3]
    remote, _ = served_master(LinkEncoderNode(NODE, lambda: angle[0], direction=-1))
    assert remote.sdo[0x6004].raw == -expected_counts(0.3)
    remote.sdo[0x6000].raw = 0x0001  # code sequence: counting direction reversed
    assert remote.sdo[0x6004].raw == expected_counts(0.3)
    remote.sdo[0x6003].raw = 1000  # preset: the present position reads 1000
    assert remote.sdo[0x6004].raw == 1000
    angle[0] = 0.3 + 2.0 * math.pi / COUNTS_PER_REV * 10
    assert remote.sdo[0x6004].raw == 1010
    assert remote.sdo[0x6003].raw == 1000


def test_transmission_types_every_nth_sync_and_on_change(wire_factory) -> None:
    angle = [0.1]
    wire, _ = started_encoder(wire_factory, angle, tpdo_transmission_type=3)
    answered = [bool(position_of(wire.sync())) for _ in range(6)]
    assert answered == [False, False, True, False, False, True]

    wire2, _ = started_encoder(wire_factory, angle, tpdo_transmission_type=0)
    assert len(position_of(wire2.sync())) == 1
    assert position_of(wire2.sync()) == []  # unchanged: acyclic synchronous sends nothing
    angle[0] = 0.2
    assert position_of(wire2.sync()) == [expected_counts(0.2)]


def test_event_timer_tpdo_on_the_emulator_clock(wire_factory) -> None:
    node = LinkEncoderNode(NODE, lambda: 0.5, tpdo_transmission_type=254, heartbeat_ms=0)
    wire = wire_factory([node])
    wire.step()
    wire.network.nmt.send_command(0x01)
    wire.step()
    assert position_of(wire.sync()) == []  # type 254 ignores SYNC; event timer is 0 = off
    # event timer 0x1800:05 = 10 ms by a raw expedited SDO download (lock-step: no SDO client)
    wire.send(0x605, bytes([0x2B, 0x00, 0x18, 0x05]) + struct.pack("<H", 10) + b"\0\0")
    (ack,) = wire.step()
    assert ack.data[0] == 0x60
    times = []
    for _ in range(10):
        if position_of(wire.step(0.005)):
            times.append(round(wire.now_s, 6))
    assert times == [0.01, 0.02, 0.03, 0.04, 0.05]


# --- faults -------------------------------------------------------------------------------------
def test_dead_node_answers_nothing_and_reboots_when_power_returns(wire_factory) -> None:
    angle = [0.2]
    wire, node = started_encoder(wire_factory, angle)
    node.fault.mode = "dead"
    wire.send(0x605, bytes([0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]))
    assert wire.step() == []
    assert wire.sync() == []
    assert wire.step(1.0) == []  # no heartbeat either
    node.fault.mode = "ok"
    assert wire.step(0.001) == []  # power is back: the node initialises first (boot-up delay)
    assert node.booting
    frames = wire.step(DEFAULT_BOOTUP_DELAY_S)
    assert [(f.arbitration_id, bytes(f.data)) for f in frames] == [(0x705, b"\x00")]
    assert node.nmt_state == 0x7F
    assert wire.sync() == []  # must be started again


def test_stale_node_keeps_the_position_of_the_fault_onset(wire_factory) -> None:
    angle = [0.2]
    wire, node = started_encoder(wire_factory, angle)
    assert position_of(wire.sync()) == [expected_counts(0.2)]
    angle[0] = 0.25
    assert position_of(wire.sync()) == [expected_counts(0.25)]
    node.fault.mode = "stale"
    for moved in (0.3, 0.4, -1.0):
        angle[0] = moved
        assert position_of(wire.sync()) == [expected_counts(0.25)]
    heartbeats = [f for f in wire.step(0.2) if f.arbitration_id == 0x705]
    assert heartbeats and heartbeats[-1].data[0] == 0x05  # still alive
    node.fault.mode = "ok"
    assert position_of(wire.sync()) == [expected_counts(-1.0)]


def noisy_positions(wire_factory, seed: int, n: int, rms: float) -> np.ndarray:
    angle = [1234 * 2.0 * math.pi / COUNTS_PER_REV]
    wire, node = started_encoder(wire_factory, angle, seed=seed)
    node.fault.mode = "noisy"
    node.fault.noise_counts_rms = rms
    return np.array([position_of(wire.sync())[0] for _ in range(n)])


def test_noisy_node_is_zero_mean_with_the_given_rms_and_deterministic(wire_factory) -> None:
    positions = noisy_positions(wire_factory, seed=7, n=2000, rms=3.0)
    error = positions - 1234
    # mean of 2000 samples of sd ~3: 4 standard errors = 0.27 counts
    assert abs(error.mean()) < 0.27
    # rounding adds variance 1/12: rms sqrt(9 + 1/12) = 3.01; 2000 samples: sd of rms ~0.05
    assert 2.85 < math.sqrt(np.mean(error.astype(float) ** 2)) < 3.17
    again = noisy_positions(wire_factory, seed=7, n=2000, rms=3.0)
    np.testing.assert_array_equal(positions, again)
    other_seed = noisy_positions(wire_factory, seed=8, n=2000, rms=3.0)
    assert not np.array_equal(positions, other_seed)


def test_bad_fault_mode_is_refused_with_a_clear_message(wire_factory) -> None:
    wire, node = started_encoder(wire_factory, [0.0])
    node.fault.mode = "daed"
    with pytest.raises(ValueError, match="fault mode must be one of"):
        wire.sync()


# --- force sensor, segment, determinism ----------------------------------------------------------
def test_force_sensor_reports_millinewtons_in_its_tpdo(served_master) -> None:
    force = [23.4567]
    remote, node = served_master(
        ForceSensorNode(7, lambda: force[0]), eds_file=FORCE_SENSOR_EDS_FILE
    )
    assert remote.sdo[0x1000].raw == 0x0002_0194
    assert remote.sdo[0x6131][1].raw == 0x0021_0000  # newton, prefix 10^0
    assert remote.sdo[0x6132][1].raw == 3
    assert remote.sdo[0x9130][1].raw == 23457
    force[0] = -5.0
    assert remote.sdo[0x9130][1].raw == -5000
    assert remote.sdo[0x1A00][1].raw == 0x9130_0120
    assert node.nmt_state == 0x7F


def test_segment_every_node_answers_one_sync_in_arbitration_order(wire_factory) -> None:
    nodes = [
        LinkEncoderNode(9, lambda: 0.9),
        ForceSensorNode(3, lambda: 1.0),
        LinkEncoderNode(4, lambda: 0.4),
    ]
    wire = wire_factory(nodes)
    boot = wire.step()
    assert [f.arbitration_id for f in boot] == [0x703, 0x704, 0x709]
    wire.network.nmt.send_command(0x01)
    wire.step()
    frames = wire.sync()
    assert [f.arbitration_id for f in frames] == [0x183, 0x184, 0x189]
    assert struct.unpack("<i", frames[2].data)[0] == expected_counts(0.9)


def test_segment_refuses_duplicate_node_ids() -> None:
    with pytest.raises(ValueError, match=r"share node ID\(s\) \[5\]"):
        CanSegment([LinkEncoderNode(5, lambda: 0.0), ForceSensorNode(5, lambda: 0.0)])


def test_node_configuration_errors_are_clear() -> None:
    with pytest.raises(ValueError, match="node ID must be 1..127"):
        LinkEncoderNode(0, lambda: 0.0)
    with pytest.raises(ValueError, match="direction must be"):
        LinkEncoderNode(5, lambda: 0.0, direction=2)
    with pytest.raises(ValueError, match="tpdo_transmission_type"):
        LinkEncoderNode(5, lambda: 0.0, tpdo_transmission_type=252)
    with pytest.raises(TypeError, match="angle_source"):
        LinkEncoderNode(5, 0.3)  # type: ignore[arg-type]


def run_scripted_session(wire_factory, seed: int) -> list[tuple[float, int, bytes]]:
    angle = [0.0]
    nodes = [LinkEncoderNode(5, lambda: angle[0], seed=seed), LinkEncoderNode(6, lambda: -angle[0])]
    nodes[0].fault.mode = "noisy"
    nodes[0].fault.noise_counts_rms = 2.0
    wire = wire_factory(nodes)
    log = []
    wire.step()
    wire.network.nmt.send_command(0x01)
    for k in range(200):
        angle[0] = 0.3 * math.sin(0.05 * k)
        wire.network.sync.transmit()
        log += [(round(wire.now_s, 6), f.arbitration_id, bytes(f.data)) for f in wire.step(0.005)]
    return log


def test_lock_step_session_is_deterministic(wire_factory) -> None:
    first = run_scripted_session(wire_factory, seed=3)
    assert first == run_scripted_session(wire_factory, seed=3)
    assert sum(1 for _, cob, _ in first if cob == 0x185) == 200
    assert sum(1 for _, cob, _ in first if cob == 0x705) == 10  # 1 s of 100 ms heartbeats
