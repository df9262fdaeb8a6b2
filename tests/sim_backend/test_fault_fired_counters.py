"""Every injected fault reports that it fired: line faults of the Dynamixel chain, sensor
faults of the CAN nodes, and the emulator server's scenario faults (its last output line), so
that a test can assert the fault it injected really happened."""

from __future__ import annotations

import math

import can
import pytest

from drivers.canbus import LinkEncoderConfig
from drivers.dynamixel import DynamixelChainConfig, DynamixelJointConfig
from drivers.dynamixel_can_bus import CanChannelConfig, DynamixelCanBus, DynamixelCanBusConfig
from sim_backend.canbus.encoder_node import LinkEncoderNode
from sim_backend.dynamixel.chain import DynamixelChain
from sim_backend.dynamixel.device import H54Device
from sim_backend.dynamixel.faults import FaultCounts, LineFaults
from sim_backend.dynamixel.protocol import Instruction, build_instruction_packet
from sim_backend.emulator_process import emulator_process
from sim_backend.scenario import FaultEvent, Scenario, parse_fault
from sim_backend.server import EmulatedJointSpec, EmulatorSpec
from tests.support.load_conditions import FUNCTIONAL_LATENCY_TIMER_MS

pytestmark = pytest.mark.timeout(90)


def test_line_fault_counts_follow_what_was_dropped_and_corrupted() -> None:
    faults = LineFaults(drop_reply_ids={3}, corrupt_next_replies=2)
    assert [faults.take_drop(3), faults.take_drop(4), faults.take_drop(3)] == [True, False, True]
    assert [faults.take_corrupt(1) for _ in range(3)] == [True, True, False]
    assert faults.fired == FaultCounts(replies_dropped=2, replies_corrupted=2)
    faults.clear()  # the line heals; the history stays
    assert not faults.take_drop(3) and faults.fired.replies_dropped == 2


def test_a_silent_id_counts_the_instructions_it_did_not_hear() -> None:
    chain = DynamixelChain([H54Device(1), H54Device(2)], faults=LineFaults(silent_ids={2}))
    assert chain.handle(build_instruction_packet(2, Instruction.PING), 0.0) == []
    assert len(chain.handle(build_instruction_packet(1, Instruction.PING), 0.0)) == 1
    assert chain.faults.fired.instructions_unheard == 1  # the PING to 1 was not for 2
    broadcast = chain.handle(build_instruction_packet(0xFE, Instruction.PING), 0.0)
    assert [reply[1][4] for reply in broadcast] == [1]
    assert chain.faults.fired.instructions_unheard == 2


def test_sensor_fault_counts_on_an_emulated_node() -> None:
    node = LinkEncoderNode(5, lambda: 0.1)
    node.poll(0.0)
    node.handle(can.Message(arbitration_id=0, is_extended_id=False, data=b"\x01\x05"), 0.0)
    sync = can.Message(arbitration_id=0x80, is_extended_id=False)
    node.fault.mode = "stale"
    node.handle(sync, 0.01)
    node.handle(sync, 0.02)
    node.fault.mode = "noisy"
    node.fault.noise_counts_rms = 5.0
    node.handle(sync, 0.03)
    node.fault.mode = "dead"
    node.handle(sync, 0.04)
    node.handle(sync, 0.05)
    counts = node.fault_counts
    assert (counts.stale_samples, counts.noisy_samples) == (2, 1)
    assert counts.frames_ignored_while_dead == 2


def test_a_fault_at_nan_or_infinity_is_refused_not_silently_skipped() -> None:
    for text in ("silent_id@nan", "silent_id@inf", "dead_encoder@1+nan", "corrupt_crc@-1"):
        with pytest.raises(ValueError, match="finite"):
            parse_fault(text)
    with pytest.raises(ValueError, match="noise must be finite"):
        FaultEvent("noisy_encoder", 0.0, noise_counts_rms=math.nan)


def test_the_emulator_reports_which_scenario_faults_fired_and_how_often() -> None:
    faults = (
        FaultEvent("silent_id", 0.05, 0.05),
        FaultEvent("dead_encoder", 0.15, 0.05),
        FaultEvent("dropped_reply", 0.25),
        FaultEvent("corrupt_crc", 0.30),
        FaultEvent("stale_encoder", 100.0),  # after the run: must not be reported
    )
    spec = EmulatorSpec(
        joints=(EmulatedJointSpec(dxl_id=1, encoder_node_id=5),), scenario=Scenario(faults=faults)
    )
    with emulator_process(spec) as emulator:
        endpoints = emulator.endpoints
        bus = DynamixelCanBus(
            DynamixelCanBusConfig(
                joint_names=("joint",),
                chains=(
                    DynamixelChainConfig(
                        port=endpoints["dynamixel_port"],
                        baudrate=endpoints["baudrate"],
                        joints=(
                            DynamixelJointConfig(
                                dxl_id=1, name="joint", min_position_rad=-1, max_position_rad=1
                            ),
                        ),
                        # generous: the emulator is another process, maybe descheduled a while
                        latency_timer_ms=FUNCTIONAL_LATENCY_TIMER_MS,
                    ),
                ),
                can_channels=(
                    CanChannelConfig(
                        "can0", endpoints["can"], encoders=(LinkEncoderConfig(5, name="joint"),)
                    ),
                ),
                link_timeout_s=0.02,
            )
        )
        with bus:
            samples = [bus.read() for _ in range(80)]  # 0.4 s of plant time
    counts = emulator.fault_counts
    assert counts["scenario_faults_started"] == [0, 1, 2, 3]
    assert counts["dynamixel"]["instructions_unheard"] >= 10  # ~10 ticks with ID 1 silent
    assert counts["dynamixel"]["replies_dropped"] == 1
    assert counts["dynamixel"]["replies_corrupted"] == 1
    assert counts["encoders"]["5"]["frames_ignored_while_dead"] >= 10
    assert counts["encoders"]["5"]["stale_samples"] == 0
    # and the driver saw them: invalid motor and link samples
    assert sum(not s.motor_valid[0] for s in samples) >= 10 + 2
    assert sum(not s.link_valid[0] for s in samples) >= 10
