"""The emulated H54 chain driven by the unmodified dynamixel-sdk: instructions and error replies.

The emulator runs in a child process (sim_backend.dynamixel.testing), the SDK talks to its pty.
Expected values come from the e-Manual (control table, error numbers), not from the emulator.
"""

from __future__ import annotations

import time
from collections.abc import Iterator

import pytest
from dynamixel_sdk import (
    COMM_RX_TIMEOUT,
    COMM_SUCCESS,
    GroupBulkRead,
    GroupBulkWrite,
    GroupSyncRead,
    GroupSyncWrite,
    PacketHandler,
)

from sim_backend.dynamixel.protocol import (
    Instruction,
    PacketParser,
    ParsedPacket,
    build_instruction_packet,
)
from sim_backend.dynamixel.testing import EmulatedChain, spawn_emulated_chain
from tests.support.load_conditions import PatientPortHandler

pytestmark = pytest.mark.timeout(60)

BAUD_4M = 4_000_000
MODEL_H54 = 54024
# e-Manual addresses (H54-200-S500-R control table)
ID_ADDR = 7
BAUD_ADDR = 8
RETURN_DELAY_ADDR = 9
OPERATING_MODE_ADDR = 11
TORQUE_LIMIT_ADDR = 30
VELOCITY_LIMIT_ADDR = 32
MAX_POSITION_LIMIT_ADDR = 36
MIN_POSITION_LIMIT_ADDR = 40
SHUTDOWN_ADDR = 48
TORQUE_ENABLE_ADDR = 562
LED_RED_ADDR = 563
GOAL_POSITION_ADDR = 596
GOAL_VELOCITY_ADDR = 600
GOAL_TORQUE_ADDR = 604
PRESENT_POSITION_ADDR = 611
PRESENT_CURRENT_ADDR = 621
REGISTERED_INSTRUCTION_ADDR = 890
STATUS_RETURN_LEVEL_ADDR = 891
HARDWARE_ERROR_STATUS_ADDR = 892

ERR_RESULT_FAIL = 1
ERR_INSTRUCTION = 2
ERR_DATA_RANGE = 4
ERR_DATA_LENGTH = 5
ERR_DATA_LIMIT = 6
ERR_ACCESS = 7
ALERT = 0x80


class Bus:
    """An opened SDK port + packet handler on an emulator's pty."""

    def __init__(self, emu: EmulatedChain, baud: int = BAUD_4M) -> None:
        self.emu = emu
        self.port = PatientPortHandler(emu.port_path)
        self.ph = PacketHandler(2.0)
        assert self.port.openPort(), f"could not open {emu.port_path}"
        assert self.port.setBaudRate(baud)

    def close(self) -> None:
        self.port.closePort()


@pytest.fixture
def bus() -> Iterator[Bus]:
    with spawn_emulated_chain(ids=(1, 2, 3), baud_index=6) as emu:
        handle = Bus(emu)
        try:
            yield handle
        finally:
            handle.close()


def to_signed32(value: int) -> int:
    return value - (1 << 32) if value & 0x8000_0000 else value


def le32(value: int) -> list[int]:
    return list((value & 0xFFFF_FFFF).to_bytes(4, "little"))


# ------------------------------------------------------------------------------------ basics


def test_ping_returns_h54_model_and_firmware(bus: Bus) -> None:
    model, comm, error = bus.ph.ping(bus.port, 2)
    assert (model, comm, error) == (MODEL_H54, COMM_SUCCESS, 0)
    model, comm, error = bus.ph.ping(bus.port, 9)  # nobody has ID 9
    assert comm == COMM_RX_TIMEOUT


def test_broadcast_ping_lists_every_device(bus: Bus) -> None:
    found, comm = bus.ph.broadcastPing(bus.port)
    assert comm == COMM_SUCCESS
    assert sorted(found) == [1, 2, 3]
    assert all(model == MODEL_H54 for model, _firmware in found.values())


def test_read_defaults_from_the_emanual(bus: Bus) -> None:
    ph, port = bus.ph, bus.port
    assert ph.read2ByteTxRx(port, 1, 0)[:2] == (MODEL_H54, COMM_SUCCESS)
    assert ph.read1ByteTxRx(port, 1, RETURN_DELAY_ADDR)[0] == 250
    assert ph.read1ByteTxRx(port, 1, OPERATING_MODE_ADDR)[0] == 3
    assert ph.read2ByteTxRx(port, 1, TORQUE_LIMIT_ADDR)[0] == 620
    assert ph.read4ByteTxRx(port, 1, VELOCITY_LIMIT_ADDR)[0] == 17_000
    assert to_signed32(ph.read4ByteTxRx(port, 1, MAX_POSITION_LIMIT_ADDR)[0]) == 250_961
    assert to_signed32(ph.read4ByteTxRx(port, 1, MIN_POSITION_LIMIT_ADDR)[0]) == -250_961
    assert ph.read1ByteTxRx(port, 1, SHUTDOWN_ADDR)[0] == 58
    assert ph.read1ByteTxRx(port, 1, STATUS_RETURN_LEVEL_ADDR)[0] == 2
    assert ph.read2ByteTxRx(port, 1, 49)[0] == 634  # Indirect Address 1 -> Indirect Data 1
    assert ph.read2ByteTxRx(port, 1, 559)[0] == 889  # Indirect Address 256


def test_write_then_read_goal_and_present_position(bus: Bus) -> None:
    ph, port = bus.ph, bus.port
    assert ph.write1ByteTxRx(port, 1, TORQUE_ENABLE_ADDR, 1) == (COMM_SUCCESS, 0)
    assert ph.write4ByteTxRx(port, 1, GOAL_POSITION_ADDR, -123_456) == (COMM_SUCCESS, 0)
    value, comm, error = ph.read4ByteTxRx(port, 1, GOAL_POSITION_ADDR)
    assert (to_signed32(value), comm, error) == (-123_456, COMM_SUCCESS, 0)
    # the "ideal" stand-in firmware: Present Position follows Goal Position with torque on
    value, comm, error = ph.read4ByteTxRx(port, 1, PRESENT_POSITION_ADDR)
    assert to_signed32(value) == -123_456
    assert bus.emu.item(1, "Goal Position") == -123_456


def test_read_spanning_items_and_the_undocumented_gap(bus: Bus) -> None:
    bus.emu.set_item(1, "Present Position", 1000)
    bus.emu.set_item(1, "Present Velocity", -5)
    bus.emu.set_item(1, "Present Current", -300)
    data, comm, error = bus.ph.readTxRx(bus.port, 1, PRESENT_POSITION_ADDR, 12)
    assert (comm, error) == (COMM_SUCCESS, 0)
    raw = bytes(data)
    assert int.from_bytes(raw[0:4], "little", signed=True) == 1000
    assert int.from_bytes(raw[4:8], "little", signed=True) == -5
    assert raw[8:10] == b"\x00\x00"  # 619..620: not in the table, read as 0
    assert int.from_bytes(raw[10:12], "little", signed=True) == -300


def test_sync_write_and_sync_read(bus: Bus) -> None:
    ph, port = bus.ph, bus.port
    for dxl_id in (1, 2, 3):
        assert ph.write1ByteTxRx(port, dxl_id, TORQUE_ENABLE_ADDR, 1) == (COMM_SUCCESS, 0)
    writer = GroupSyncWrite(port, ph, GOAL_POSITION_ADDR, 4)
    goals = {1: 1111, 2: -2222, 3: 250_961}
    for dxl_id, goal in goals.items():
        assert writer.addParam(dxl_id, le32(goal))
    assert writer.txPacket() == COMM_SUCCESS
    reader = GroupSyncRead(port, ph, PRESENT_POSITION_ADDR, 4)
    for dxl_id in (3, 1, 2):
        reader.addParam(dxl_id)
    assert reader.txRxPacket() == COMM_SUCCESS
    for dxl_id, goal in goals.items():
        assert reader.isAvailable(dxl_id, PRESENT_POSITION_ADDR, 4)
        assert to_signed32(reader.getData(dxl_id, PRESENT_POSITION_ADDR, 4)) == goal


def test_reboot_answers_then_restores_ram_defaults_and_keeps_eeprom(bus: Bus) -> None:
    ph, port = bus.ph, bus.port
    assert ph.write1ByteTxRx(port, 2, RETURN_DELAY_ADDR, 7) == (COMM_SUCCESS, 0)  # EEPROM
    assert ph.write1ByteTxRx(port, 2, LED_RED_ADDR, 200) == (COMM_SUCCESS, 0)  # RAM
    assert ph.write1ByteTxRx(port, 2, TORQUE_ENABLE_ADDR, 1) == (COMM_SUCCESS, 0)
    assert ph.reboot(port, 2) == (COMM_SUCCESS, 0)
    assert ph.ping(port, 2)[1] == COMM_RX_TIMEOUT  # rebooting: silent
    deadline = time.monotonic() + 3.0
    while ph.ping(port, 2)[1] != COMM_SUCCESS:
        assert time.monotonic() < deadline, "device did not come back after REBOOT"
    assert ph.read1ByteTxRx(port, 2, TORQUE_ENABLE_ADDR)[0] == 0
    assert ph.read1ByteTxRx(port, 2, LED_RED_ADDR)[0] == 0
    assert ph.read1ByteTxRx(port, 2, RETURN_DELAY_ADDR)[0] == 7


def test_bulk_write_and_bulk_read(bus: Bus) -> None:
    ph, port = bus.ph, bus.port
    writer = GroupBulkWrite(port, ph)
    assert writer.addParam(1, GOAL_POSITION_ADDR, 4, le32(-777))
    assert writer.addParam(3, LED_RED_ADDR, 1, [99])
    assert writer.txPacket() == COMM_SUCCESS
    reader = GroupBulkRead(port, ph)
    assert reader.addParam(3, LED_RED_ADDR, 1)
    assert reader.addParam(1, GOAL_POSITION_ADDR, 4)
    assert reader.addParam(2, 0, 2)  # Model Number
    assert reader.txRxPacket() == COMM_SUCCESS
    assert reader.getData(3, LED_RED_ADDR, 1) == 99
    assert to_signed32(reader.getData(1, GOAL_POSITION_ADDR, 4)) == -777
    assert reader.getData(2, 0, 2) == MODEL_H54


def test_reg_write_then_action(bus: Bus) -> None:
    ph, port = bus.ph, bus.port
    assert ph.regWriteTxRx(port, 2, GOAL_VELOCITY_ADDR, 4, le32(-1500)) == (COMM_SUCCESS, 0)
    assert ph.read1ByteTxRx(port, 2, REGISTERED_INSTRUCTION_ADDR)[0] == 1
    assert to_signed32(ph.read4ByteTxRx(port, 2, GOAL_VELOCITY_ADDR)[0]) == 0  # not yet
    assert ph.action(port, 0xFE) == COMM_SUCCESS  # broadcast ACTION: no status to wait for
    assert to_signed32(ph.read4ByteTxRx(port, 2, GOAL_VELOCITY_ADDR)[0]) == -1500
    assert ph.read1ByteTxRx(port, 2, REGISTERED_INSTRUCTION_ADDR)[0] == 0


def test_unicast_action_sends_a_status_the_sdk_does_not_wait_for(bus: Bus) -> None:
    ph, port = bus.ph, bus.port
    assert ph.regWriteTxRx(port, 3, LED_RED_ADDR, 1, [33]) == (COMM_SUCCESS, 0)
    port.clearPort()
    assert ph.action(port, 3) == COMM_SUCCESS  # returns without reading a reply
    assert [(r.packet_id, r.params[0]) for r in receive_raw(bus, expected=1)] == [(3, 0)]
    assert ph.read1ByteTxRx(port, 3, LED_RED_ADDR)[0] == 33
    # ACTION with nothing registered: Instruction Error (e-Manual)
    port.clearPort()
    assert ph.action(port, 3) == COMM_SUCCESS
    assert [r.params[0] for r in receive_raw(bus, expected=1)] == [ERR_INSTRUCTION]


def test_factory_reset_keeps_id_and_baud_with_option_2_and_broadcast_all_is_refused() -> None:
    with spawn_emulated_chain(ids=(5,), baud_index=6) as emu:
        bus = Bus(emu)
        ph, port = bus.ph, bus.port
        assert ph.write1ByteTxRx(port, 5, RETURN_DELAY_ADDR, 3) == (COMM_SUCCESS, 0)
        assert ph.factoryReset(port, 0xFE, 0xFF)[0] == COMM_SUCCESS  # broadcast: no reply
        time.sleep(0.02)
        assert ph.read1ByteTxRx(port, 5, RETURN_DELAY_ADDR)[:2] == (3, COMM_SUCCESS)  # refused
        assert ph.factoryReset(port, 5, 0x02) == (COMM_SUCCESS, 0)
        deadline = time.monotonic() + 3.0
        while ph.ping(port, 5)[1] != COMM_SUCCESS:
            assert time.monotonic() < deadline, "device did not come back after FACTORY_RESET"
        assert ph.read1ByteTxRx(port, 5, RETURN_DELAY_ADDR)[0] == 250
        assert ph.read1ByteTxRx(port, 5, BAUD_ADDR)[0] == 6  # kept by option 0x02
        assert ph.factoryReset(port, 5, 0xFF) == (COMM_SUCCESS, 0)
        deadline = time.monotonic() + 3.0
        while ph.ping(port, 1)[1] != COMM_SUCCESS:  # "reset all": back to ID 1
            assert time.monotonic() < deadline, "device did not come back as ID 1"
        bus.close()


# ------------------------------------------------------------------------------ errors


def test_eeprom_write_with_torque_on_is_an_access_error(bus: Bus) -> None:
    ph, port = bus.ph, bus.port
    assert ph.write1ByteTxRx(port, 1, TORQUE_ENABLE_ADDR, 1) == (COMM_SUCCESS, 0)
    assert ph.write1ByteTxRx(port, 1, RETURN_DELAY_ADDR, 0) == (COMM_SUCCESS, ERR_ACCESS)
    assert ph.read1ByteTxRx(port, 1, RETURN_DELAY_ADDR)[0] == 250


def test_read_only_write_is_an_access_error(bus: Bus) -> None:
    ph, port = bus.ph, bus.port
    assert ph.write4ByteTxRx(port, 1, PRESENT_POSITION_ADDR, 5) == (COMM_SUCCESS, ERR_ACCESS)
    assert ph.write2ByteTxRx(port, 1, 0, 1) == (COMM_SUCCESS, ERR_ACCESS)  # Model Number


def test_goal_position_beyond_limits_is_a_data_limit_error_and_changes_nothing(bus: Bus) -> None:
    ph, port = bus.ph, bus.port
    assert ph.write4ByteTxRx(port, 1, GOAL_POSITION_ADDR, 1000) == (COMM_SUCCESS, 0)
    assert ph.write4ByteTxRx(port, 1, GOAL_POSITION_ADDR, 250_962) == (COMM_SUCCESS, ERR_DATA_LIMIT)
    assert ph.write4ByteTxRx(port, 1, GOAL_POSITION_ADDR, -250_962) == (
        COMM_SUCCESS,
        ERR_DATA_LIMIT,
    )
    assert to_signed32(ph.read4ByteTxRx(port, 1, GOAL_POSITION_ADDR)[0]) == 1000
    assert ph.write4ByteTxRx(port, 1, MAX_POSITION_LIMIT_ADDR, 500) == (COMM_SUCCESS, 0)
    assert ph.write4ByteTxRx(port, 1, GOAL_POSITION_ADDR, 501) == (COMM_SUCCESS, ERR_DATA_LIMIT)
    assert ph.write4ByteTxRx(port, 1, GOAL_POSITION_ADDR, 500) == (COMM_SUCCESS, 0)


def test_range_and_length_errors(bus: Bus) -> None:
    ph, port = bus.ph, bus.port
    assert ph.write1ByteTxRx(port, 1, TORQUE_ENABLE_ADDR, 2) == (COMM_SUCCESS, ERR_DATA_RANGE)
    assert ph.write2ByteTxRx(port, 1, GOAL_POSITION_ADDR, 7) == (COMM_SUCCESS, ERR_DATA_LENGTH)
    assert ph.write2ByteTxRx(port, 1, GOAL_TORQUE_ADDR, 621) == (COMM_SUCCESS, ERR_DATA_LIMIT)


def test_corrupted_crc_written_raw_gets_a_crc_error_status(bus: Bus) -> None:
    frame = bytearray(
        build_instruction_packet(2, Instruction.WRITE, LED_RED_ADDR.to_bytes(2, "little") + b"\x05")
    )
    frame[-1] ^= 0x5A
    bus.port.clearPort()
    bus.port.writePort(frame)
    replies = receive_raw(bus, expected=1)
    assert [(r.packet_id, r.params[0]) for r in replies] == [(2, 3)]  # CRC Error (3)
    assert bus.ph.read1ByteTxRx(bus.port, 2, LED_RED_ADDR)[0] == 0  # not executed


def test_unknown_instruction_is_an_instruction_error(bus: Bus) -> None:
    # CLEAR (0x10) exists for X/MX firmware 42+, not for the legacy Pro
    assert bus.ph.clearMultiTurn(bus.port, 1) == (COMM_SUCCESS, ERR_INSTRUCTION)
    # FAST_SYNC_READ is broadcast and unknown to the legacy Pro: nobody answers
    reader = GroupSyncRead(bus.port, bus.ph, PRESENT_POSITION_ADDR, 4)
    reader.addParam(1)
    assert reader.fastSyncRead() == COMM_RX_TIMEOUT


def test_status_return_level_through_the_sdk(bus: Bus) -> None:
    ph, port = bus.ph, bus.port
    assert ph.write1ByteTxRx(port, 3, STATUS_RETURN_LEVEL_ADDR, 1)[0] == COMM_RX_TIMEOUT
    assert ph.read1ByteTxRx(port, 3, STATUS_RETURN_LEVEL_ADDR)[:2] == (1, COMM_SUCCESS)
    assert ph.write1ByteTxRx(port, 3, LED_RED_ADDR, 17)[0] == COMM_RX_TIMEOUT  # executed
    assert ph.read1ByteTxRx(port, 3, LED_RED_ADDR)[0] == 17
    assert ph.write1ByteTxRx(port, 3, STATUS_RETURN_LEVEL_ADDR, 0)[0] == COMM_RX_TIMEOUT
    assert ph.read1ByteTxRx(port, 3, LED_RED_ADDR)[1] == COMM_RX_TIMEOUT
    assert ph.ping(port, 3)[:2] == (MODEL_H54, COMM_SUCCESS)  # PING always answers


# ------------------------------------------------------------------------------ stuffing


def test_byte_stuffing_both_ways(bus: Bus) -> None:
    """0x00FDFFFF is FF FF FD 00 on the wire. The SDK sends it unstuffed (its addStuffing
    result is discarded) and the device reads it right; our status packets are stuffed and
    the SDK unstuffs them, in single reads and in a sync read."""
    ph, port = bus.ph, bus.port
    value = 0x00FDFFFF
    assert ph.write4ByteTxRx(port, 1, 13, value) == (COMM_SUCCESS, 0)  # Homing Offset
    assert bus.emu.item(1, "Homing Offset") == value
    assert ph.read4ByteTxRx(port, 1, 13)[:2] == (value, COMM_SUCCESS)
    bus.emu.set_item(2, "Present Position", value)
    bus.emu.set_item(3, "Present Position", value)
    reader = GroupSyncRead(port, ph, PRESENT_POSITION_ADDR, 4)
    for dxl_id in (2, 3):
        reader.addParam(dxl_id)
    assert reader.txRxPacket() == COMM_SUCCESS
    assert [reader.getData(i, PRESENT_POSITION_ADDR, 4) for i in (2, 3)] == [value, value]
    # four Indirect Data bytes (self-mapped by default) carrying FF FF FD 00
    assert ph.writeTxRx(port, 1, 634, 4, [0xFF, 0xFF, 0xFD, 0x00]) == (COMM_SUCCESS, 0)
    assert ph.readTxRx(port, 1, 634, 4)[0] == [0xFF, 0xFF, 0xFD, 0x00]


# ------------------------------------------------------------------------------ sync read


def test_sync_read_of_a_missing_id_in_the_middle(bus: Bus) -> None:
    """ROBOTIS (DynamixelSDK #364): devices after a silent one in the list do not answer."""
    ph, port = bus.ph, bus.port
    bus.emu.faults(silent_ids={2})
    reader = GroupSyncRead(port, ph, PRESENT_POSITION_ADDR, 4)
    for dxl_id in (1, 2, 3):
        reader.addParam(dxl_id)
    assert reader.txRxPacket() == COMM_RX_TIMEOUT
    # what was on the wire: only ID 1's status
    port.clearPort()
    assert ph.syncReadTx(port, PRESENT_POSITION_ADDR, 4, [1, 2, 3], 3, False) == COMM_SUCCESS
    port.is_using = False
    assert [r.packet_id for r in receive_raw(bus, expected=3, wait_s=0.05)] == [1]
    bus.emu.clear_faults()
    assert reader.txRxPacket() == COMM_SUCCESS


def test_indirect_map_reads_position_and_hardware_error_in_one_sync_read(bus: Bus) -> None:
    ph, port = bus.ph, bus.port
    targets = [611, 612, 613, 614, HARDWARE_ERROR_STATUS_ADDR]
    for dxl_id in (1, 2):
        for n, target in enumerate(targets, start=1):
            assert ph.write2ByteTxRx(port, dxl_id, 49 + 2 * (n - 1), target) == (COMM_SUCCESS, 0)
    bus.emu.set_item(1, "Present Position", -4242)
    bus.emu.set_item(2, "Present Position", 99)
    bus.emu.raise_hardware_error(2, 0x20)  # Overload
    reader = GroupSyncRead(port, ph, 634, 5)
    reader.addParam(1)
    reader.addParam(2)
    assert reader.txRxPacket() == COMM_SUCCESS
    assert to_signed32(reader.getData(1, 634, 4)) == -4242
    assert reader.getData(1, 638, 1) == 0
    assert to_signed32(reader.getData(2, 634, 4)) == 99
    assert reader.getData(2, 638, 1) == 0x20


# ------------------------------------------------------------------------------ shutdown


def test_overload_shutdown_alert_torque_off_refused_until_reboot(bus: Bus) -> None:
    ph, port = bus.ph, bus.port
    assert ph.write1ByteTxRx(port, 1, TORQUE_ENABLE_ADDR, 1) == (COMM_SUCCESS, 0)
    bus.emu.raise_hardware_error(1, 0x20)  # Overload: in the default Shutdown mask 58
    assert bus.emu.in_shutdown(1)
    value, comm, error = ph.read1ByteTxRx(port, 1, TORQUE_ENABLE_ADDR)
    assert (value, comm, error) == (0, COMM_SUCCESS, ALERT)
    assert ph.ping(port, 1)[2] == ALERT
    assert ph.read1ByteTxRx(port, 1, HARDWARE_ERROR_STATUS_ADDR)[:3] == (0x20, COMM_SUCCESS, ALERT)
    assert ph.write1ByteTxRx(port, 1, TORQUE_ENABLE_ADDR, 1) == (
        COMM_SUCCESS,
        ALERT | ERR_RESULT_FAIL,
    )
    assert ph.read1ByteTxRx(port, 1, TORQUE_ENABLE_ADDR)[0] == 0
    assert ph.ping(port, 2)[2] == 0  # the others are fine
    assert ph.reboot(port, 1) == (COMM_SUCCESS, ALERT)  # status sent before the reboot
    deadline = time.monotonic() + 3.0
    while ph.ping(port, 1)[1] != COMM_SUCCESS:
        assert time.monotonic() < deadline, "device did not come back after REBOOT"
    assert ph.read1ByteTxRx(port, 1, HARDWARE_ERROR_STATUS_ADDR)[:3] == (0, COMM_SUCCESS, 0)
    assert ph.write1ByteTxRx(port, 1, TORQUE_ENABLE_ADDR, 1) == (COMM_SUCCESS, 0)
    assert ph.read1ByteTxRx(port, 1, TORQUE_ENABLE_ADDR)[0] == 1


def test_delayed_hardware_error_hook(bus: Bus) -> None:
    bus.emu.raise_hardware_error(3, 0x04, delay_s=0.05)  # Overheating: alert, no shutdown
    assert bus.ph.ping(bus.port, 3)[2] == 0
    time.sleep(0.1)
    assert bus.ph.ping(bus.port, 3)[2] == ALERT
    assert not bus.emu.in_shutdown(3)


def receive_raw(bus: Bus, expected: int, wait_s: float = 0.5) -> list[ParsedPacket]:
    """Status packets that reach the port within `wait_s` (stops early at `expected`)."""
    parser = PacketParser()
    found = []
    deadline = time.monotonic() + wait_s
    while time.monotonic() < deadline and len(found) < expected:
        found += parser.feed(bytes(bus.port.readPort(1024)), 0.0)
        time.sleep(0.001)
    return found
