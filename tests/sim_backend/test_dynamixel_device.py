"""Device and line semantics of the emulated H54 chain, in-process and exact.

Instruction packets are built byte-exact and handed to `DynamixelChain.handle`; replies are
parsed back. Expected values come from the e-Manual (control table, error numbers, rules) and
from the wire model's formula, not from the emulator's own output.
"""

from __future__ import annotations

import pytest

from sim_backend.dynamixel.chain import DynamixelChain
from sim_backend.dynamixel.device import H54Device
from sim_backend.dynamixel.faults import LineFaults
from sim_backend.dynamixel.protocol import (
    BROADCAST_ID,
    ErrorCode,
    Instruction,
    build_instruction_packet,
    parse_packet,
)

pytestmark = pytest.mark.timeout(30)

ALERT = 0x80
OVERLOAD = 0x20
OVERHEATING = 0x04


def u16(value: int) -> bytes:
    return value.to_bytes(2, "little")


def s32(value: int) -> bytes:
    return value.to_bytes(4, "little", signed=True)


class Replies(list):
    """[(reply_id, error, data, due_s)] from one instruction."""


def send(
    chain: DynamixelChain,
    packet_id: int,
    instruction: int,
    params: bytes = b"",
    *,
    now_s: float = 0.0,
    line_baud_bps: int | None = None,
) -> Replies:
    frame = build_instruction_packet(packet_id, instruction, params)
    replies = Replies()
    for due_s, status in chain.handle(frame, now_s, line_baud_bps=line_baud_bps):
        packet = parse_packet(status)
        assert packet.crc_ok and packet.instruction == Instruction.STATUS
        replies.append((packet.packet_id, packet.params[0], packet.params[1:], due_s))
    return replies


def write(chain: DynamixelChain, dxl_id: int, address: int, data: bytes) -> int:
    (reply,) = send(chain, dxl_id, Instruction.WRITE, u16(address) + data)
    assert reply[0] == dxl_id
    return reply[1]


def read(chain: DynamixelChain, dxl_id: int, address: int, length: int) -> tuple[int, bytes]:
    (reply,) = send(chain, dxl_id, Instruction.READ, u16(address) + u16(length))
    return reply[1], reply[2]


@pytest.fixture
def one() -> DynamixelChain:
    return DynamixelChain([H54Device(1)])


@pytest.fixture
def three() -> DynamixelChain:
    return DynamixelChain(
        [H54Device(i, eeprom_overrides={"Return Delay Time": 0}) for i in (1, 2, 3)]
    )


# ------------------------------------------------------------------------- access rules


def test_write_and_read_signed_goal_position(one: DynamixelChain) -> None:
    assert write(one, 1, 596, s32(-250_961)) == ErrorCode.NONE
    assert read(one, 1, 596, 4) == (ErrorCode.NONE, s32(-250_961))
    assert one.device(1).item("Goal Position") == -250_961


def test_read_only_and_undefined_addresses_are_access_errors(one: DynamixelChain) -> None:
    assert write(one, 1, 611, s32(5)) == ErrorCode.ACCESS  # Present Position
    assert write(one, 1, 0, u16(1)) == ErrorCode.ACCESS  # Model Number
    assert write(one, 1, 892, b"\x00") == ErrorCode.ACCESS  # Hardware Error Status
    assert write(one, 1, 566, b"\x00") == ErrorCode.ACCESS  # undefined
    assert write(one, 1, 563, b"\x01\x02\x03\x04") == ErrorCode.ACCESS  # runs into 566
    assert one.device(1).item("LED Red") == 0  # nothing of the failed write landed
    assert read(one, 1, 890, 4) == (ErrorCode.ACCESS, b"")  # past the end of the table
    assert read(one, 1, 619, 2) == (ErrorCode.NONE, b"\x00\x00")  # undocumented gap


def test_eeprom_is_locked_while_torque_is_on(one: DynamixelChain) -> None:
    assert write(one, 1, 562, b"\x01") == ErrorCode.NONE
    assert write(one, 1, 9, b"\x00") == ErrorCode.ACCESS
    assert write(one, 1, 36, s32(1000)) == ErrorCode.ACCESS
    assert one.device(1).item("Return Delay Time") == 250
    assert write(one, 1, 562, b"\x00") == ErrorCode.NONE
    assert write(one, 1, 9, b"\x00") == ErrorCode.NONE


def test_partial_item_writes_are_data_length_errors(one: DynamixelChain) -> None:
    assert write(one, 1, 596, b"\x01\x02") == ErrorCode.DATA_LENGTH
    assert write(one, 1, 31, b"\x01") == ErrorCode.DATA_LENGTH  # upper byte of Torque Limit
    assert write(one, 1, 596, b"") == ErrorCode.DATA_LENGTH


@pytest.mark.parametrize(
    ("address", "data"),
    [
        (562, b"\x02"),  # Torque Enable 0..1
        (11, b"\x02"),  # Operating Mode {0, 1, 3, 4}
        (7, b"\xfd"),  # ID 0..252
        (8, b"\x09"),  # Baud Rate 0..8
        (9, b"\xff"),  # Return Delay Time 0..254
        (30, u16(1861)),  # Torque Limit 0..1860
        (49, u16(561)),  # Indirect Address 1: 562..892
        (49, u16(893)),
        (891, b"\x03"),  # Status Return Level 0..2
        (21, b"\x65"),  # Temperature Limit 0..100
    ],
)
def test_values_outside_the_range_are_data_range_errors(
    one: DynamixelChain, address: int, data: bytes
) -> None:
    before = read(one, 1, address, len(data))
    assert write(one, 1, address, data) == ErrorCode.DATA_RANGE
    assert read(one, 1, address, len(data)) == before


def test_limits_are_data_limit_errors_and_change_nothing(one: DynamixelChain) -> None:
    assert write(one, 1, 596, s32(1000)) == ErrorCode.NONE
    assert write(one, 1, 596, s32(250_962)) == ErrorCode.DATA_LIMIT
    assert write(one, 1, 596, s32(-250_962)) == ErrorCode.DATA_LIMIT
    assert one.device(1).item("Goal Position") == 1000
    assert write(one, 1, 600, s32(17_001)) == ErrorCode.DATA_LIMIT  # Velocity Limit 17,000
    assert write(one, 1, 600, s32(-17_001)) == ErrorCode.DATA_LIMIT
    assert write(one, 1, 600, s32(-17_000)) == ErrorCode.NONE
    assert write(one, 1, 604, (621).to_bytes(2, "little", signed=True)) == ErrorCode.DATA_LIMIT
    assert write(one, 1, 604, (-620).to_bytes(2, "little", signed=True)) == ErrorCode.NONE
    assert write(one, 1, 606, s32(-1)) == ErrorCode.DATA_LIMIT
    assert write(one, 1, 606, s32(256)) == ErrorCode.DATA_LIMIT  # Acceleration Limit 255
    # tighter Max Position Limit (EEPROM, torque off) moves the bound
    assert write(one, 1, 36, s32(500)) == ErrorCode.NONE
    assert write(one, 1, 596, s32(501)) == ErrorCode.DATA_LIMIT
    # Extended Position Control Mode ignores the position limits (e-Manual)
    assert write(one, 1, 11, b"\x04") == ErrorCode.NONE
    assert write(one, 1, 596, s32(0x12345678)) == ErrorCode.NONE


def test_multi_item_write_is_all_or_nothing(one: DynamixelChain) -> None:
    assert write(one, 1, 563, b"\x0a\x0b\x0c") == ErrorCode.NONE  # LED Red, Green, Blue
    assert read(one, 1, 562, 4) == (ErrorCode.NONE, b"\x00\x0a\x0b\x0c")
    # Torque Enable 2 is out of range: the LED bytes in the same packet are not written either
    assert write(one, 1, 562, b"\x02\x01\x01\x01") == ErrorCode.DATA_RANGE
    assert read(one, 1, 563, 3) == (ErrorCode.NONE, b"\x0a\x0b\x0c")


def test_external_port_data_is_writable_only_in_output_mode(one: DynamixelChain) -> None:
    assert write(one, 1, 626, u16(1)) == ErrorCode.ACCESS  # mode 0: analogue input
    assert write(one, 1, 44, b"\x01") == ErrorCode.NONE  # mode 1: digital output
    assert write(one, 1, 626, u16(1)) == ErrorCode.NONE


# ------------------------------------------------------------------------- indirect


def test_indirect_example_1_led_red(one: DynamixelChain) -> None:
    """e-Manual Indirect Address, Example 1: LED Red (563) through Indirect Data 1 (634)."""
    assert write(one, 1, 49, u16(563)) == ErrorCode.NONE
    assert write(one, 1, 634, b"\x01") == ErrorCode.NONE
    assert one.device(1).item("LED Red") == 1
    assert write(one, 1, 634, b"\x00") == ErrorCode.NONE
    assert one.device(1).item("LED Red") == 0


def test_indirect_example_2_goal_position(one: DynamixelChain) -> None:
    """e-Manual Example 2: Goal Position through Indirect Data 2..5, value 0x12345678 (taken in
    Extended Position mode, where that value is within limits)."""
    assert write(one, 1, 11, b"\x04") == ErrorCode.NONE
    for n, target in zip(range(2, 6), range(596, 600), strict=True):
        assert write(one, 1, 49 + 2 * (n - 1), u16(target)) == ErrorCode.NONE
    assert write(one, 1, 635, s32(0x12345678)) == ErrorCode.NONE
    assert read(one, 1, 596, 4) == (ErrorCode.NONE, bytes((0x78, 0x56, 0x34, 0x12)))


def test_indirect_inherits_size_range_access_and_limits(one: DynamixelChain) -> None:
    for n, target in enumerate(range(596, 599), start=1):  # only 3 of Goal Position's 4 bytes
        assert write(one, 1, 49 + 2 * (n - 1), u16(target)) == ErrorCode.NONE
    assert write(one, 1, 634, b"\x01\x02\x03") == ErrorCode.DATA_LENGTH
    assert write(one, 1, 55, u16(599)) == ErrorCode.NONE  # Indirect Address 4 -> 4th byte
    assert write(one, 1, 634, s32(300_000)) == ErrorCode.DATA_LIMIT
    assert write(one, 1, 634, s32(-42)) == ErrorCode.NONE
    assert one.device(1).item("Goal Position") == -42
    assert write(one, 1, 59, u16(892)) == ErrorCode.NONE  # Indirect Data 6 -> HES (read-only)
    assert write(one, 1, 639, b"\x00") == ErrorCode.ACCESS
    assert write(one, 1, 61, u16(562)) == ErrorCode.NONE  # Indirect Data 7 -> Torque Enable
    assert write(one, 1, 640, b"\x05") == ErrorCode.DATA_RANGE


def test_indirect_read_maps_present_position_and_hardware_error(one: DynamixelChain) -> None:
    device = one.device(1)
    for n, target in enumerate([611, 612, 613, 614, 892], start=1):
        assert write(one, 1, 49 + 2 * (n - 1), u16(target)) == ErrorCode.NONE
    device.set_item("Present Position", -7)
    device.raise_hardware_error(OVERHEATING)  # not in the default Shutdown mask (58)
    error, data = read(one, 1, 634, 5)
    assert error == ALERT
    assert data == s32(-7) + bytes((OVERHEATING,))
    assert device.item("Indirect Data 5") == OVERHEATING


# ------------------------------------------------------------------------- instructions


def test_ping_params(one: DynamixelChain) -> None:
    ((reply_id, error, data, _),) = send(one, 1, Instruction.PING)
    assert (reply_id, error, data) == (1, 0, bytes((0x08, 0xD3, 1)))  # 54024 = 0xD308, fw 1


def test_reg_write_and_action(one: DynamixelChain) -> None:
    device = one.device(1)
    ((_, error, _, _),) = send(one, 1, Instruction.ACTION)
    assert error == ErrorCode.INSTRUCTION  # ACTION without REG_WRITE
    ((_, error, _, _),) = send(one, 1, Instruction.REG_WRITE, u16(596) + s32(300_000))
    assert error == ErrorCode.DATA_LIMIT and device.item("Registered Instruction") == 0
    ((_, error, _, _),) = send(one, 1, Instruction.REG_WRITE, u16(596) + s32(4321))
    assert error == ErrorCode.NONE and device.item("Registered Instruction") == 1
    assert device.item("Goal Position") == 0
    ((_, error, _, _),) = send(one, 1, Instruction.ACTION)
    assert error == ErrorCode.NONE
    assert device.item("Goal Position") == 4321 and device.item("Registered Instruction") == 0


def test_status_return_level(one: DynamixelChain) -> None:
    # the level is consulted after execution: the write that sets 1 is already not answered
    assert send(one, 1, Instruction.WRITE, u16(891) + b"\x01") == []
    assert send(one, 1, Instruction.WRITE, u16(563) + b"\x07") == []  # executed, no reply
    assert one.device(1).item("LED Red") == 7
    assert read(one, 1, 563, 1) == (ErrorCode.NONE, b"\x07")
    assert len(send(one, 1, Instruction.PING)) == 1
    assert send(one, 1, Instruction.WRITE, u16(891) + b"\x00") == []
    assert send(one, 1, Instruction.READ, u16(563) + u16(1)) == []
    assert len(send(one, 1, Instruction.PING)) == 1  # PING always answers


def test_reboot_status_first_then_ram_reset_and_silence(one: DynamixelChain) -> None:
    device = one.device(1)
    calls = []
    device.add_reboot_listener(lambda: calls.append("reboot"))
    assert write(one, 1, 9, b"\x05") == ErrorCode.NONE  # EEPROM
    assert write(one, 1, 562, b"\x01\x09") == ErrorCode.NONE  # torque on, LED Red 9
    device.set_item("Present Position", 1234)
    device.raise_hardware_error(OVERLOAD)
    assert device.in_shutdown and not device.torque_enabled
    ((_, error, _, _),) = send(one, 1, Instruction.REBOOT, now_s=10.0)
    assert error == ALERT  # built before the reboot: carries the pre-reboot alert
    assert calls == ["reboot"]
    assert not device.available(10.0 + device.reboot_time_s / 2)
    assert send(one, 1, Instruction.PING, now_s=10.0 + device.reboot_time_s / 2) == []
    assert device.available(10.0 + device.reboot_time_s)
    assert not device.in_shutdown
    assert device.item("Hardware Error Status") == 0
    assert device.item("LED Red") == 0 and device.item("Status Return Level") == 2
    assert device.item("Return Delay Time") == 5  # EEPROM kept
    assert device.item("Present Position") == 1234  # measured value kept
    assert device.item("Goal Position") == 1234  # holds where it is


def test_factory_reset_options(three: DynamixelChain) -> None:
    device = three.device(2)
    assert write(three, 2, 8, b"\x03") == ErrorCode.NONE  # Baud Rate 1M
    assert write(three, 2, 36, s32(999)) == ErrorCode.NONE
    ((_, error, _, _),) = send(three, 2, Instruction.FACTORY_RESET, b"\x03")
    assert error == ErrorCode.DATA_RANGE
    assert write(three, 2, 562, b"\x01") == ErrorCode.NONE
    ((_, error, _, _),) = send(three, 2, Instruction.FACTORY_RESET, b"\x02")
    assert error == ErrorCode.ACCESS  # torque on locks the EEPROM
    assert write(three, 2, 562, b"\x00") == ErrorCode.NONE
    ((_, error, _, _),) = send(three, 2, Instruction.FACTORY_RESET, b"\x02", now_s=1.0)
    assert error == ErrorCode.NONE
    assert device.item("Max Position Limit") == 250_961 and device.item("Return Delay Time") == 250
    assert device.item("Baud Rate") == 3 and device.dxl_id == 2  # kept by 0x02
    assert device.item("Model Number") == 54024  # identity kept
    send(three, 2, Instruction.FACTORY_RESET, b"\x01", now_s=2.0)
    assert device.item("Baud Rate") == 1 and device.dxl_id == 2
    send(three, 2, Instruction.FACTORY_RESET, b"\xff", now_s=3.0)
    assert device.dxl_id == 1  # 0xFF resets the ID too


def test_broadcast_factory_reset_all_is_refused(three: DynamixelChain) -> None:
    assert write(three, 3, 36, s32(999)) == ErrorCode.NONE
    assert send(three, BROADCAST_ID, Instruction.FACTORY_RESET, b"\xff") == []
    assert three.device(3).item("Max Position Limit") == 999
    assert send(three, BROADCAST_ID, Instruction.FACTORY_RESET, b"\x02") == []
    assert three.device(3).item("Max Position Limit") == 250_961


def test_unknown_and_unsupported_instructions(one: DynamixelChain) -> None:
    clear = bytes((0x01, 0x44, 0x58, 0x4C, 0x22))
    assert send(one, 1, Instruction.CLEAR, clear)[0][1] == ErrorCode.INSTRUCTION
    assert send(one, 1, 0x7E)[0][1] == ErrorCode.INSTRUCTION
    assert send(one, 1, Instruction.SYNC_READ, u16(611) + u16(4) + b"\x01")[0][1] == 2
    # broadcast instructions the legacy Pro does not know: no reply at all
    assert send(one, BROADCAST_ID, Instruction.FAST_SYNC_READ, u16(611) + u16(4) + b"\x01") == []
    assert send(one, BROADCAST_ID, 0x7E) == []
    assert send(one, BROADCAST_ID, Instruction.READ, u16(611) + u16(4)) == []


def test_id_change_replies_with_the_old_id(one: DynamixelChain) -> None:
    ((reply_id, error, _, _),) = send(one, 1, Instruction.WRITE, u16(7) + b"\x09")
    assert (reply_id, error) == (1, ErrorCode.NONE)
    assert send(one, 1, Instruction.PING) == []
    assert send(one, 9, Instruction.PING)[0][0] == 9


def test_crc_error_reply_only_for_our_unicast_ids(three: DynamixelChain) -> None:
    for packet_id, expected in ((2, [(2, ErrorCode.CRC)]), (7, []), (BROADCAST_ID, [])):
        frame = bytearray(
            build_instruction_packet(packet_id, Instruction.WRITE, u16(563) + b"\x05")
        )
        frame[-2] ^= 0x01
        replies = three.handle(bytes(frame), 0.0)
        got = [(parse_packet(r).packet_id, parse_packet(r).params[0]) for _, r in replies]
        assert got == expected
    assert all(three.device(i).item("LED Red") == 0 for i in (1, 2, 3))


def test_hardware_error_bits_and_shutdown(one: DynamixelChain) -> None:
    device = one.device(1)
    assert write(one, 1, 562, b"\x01") == ErrorCode.NONE
    device.raise_hardware_error(OVERHEATING)  # not enabled in Shutdown 58
    assert device.torque_enabled and not device.in_shutdown
    assert read(one, 1, 892, 1) == (ALERT, bytes((OVERHEATING,)))
    device.clear_hardware_error(OVERHEATING)
    assert read(one, 1, 892, 1) == (0, b"\x00")
    device.raise_hardware_error(OVERLOAD)
    assert device.in_shutdown and not device.torque_enabled
    assert write(one, 1, 562, b"\x01") == ALERT | ErrorCode.RESULT_FAIL
    assert not device.torque_enabled
    assert write(one, 1, 562, b"\x00") == ALERT  # accepted, alert still set
    with pytest.raises(ValueError, match="0x3F"):
        device.raise_hardware_error(0x40)


# ------------------------------------------------------------------------- chain


def test_broadcast_ping_in_id_order(three: DynamixelChain) -> None:
    chain = DynamixelChain([H54Device(i) for i in (3, 1, 2)])
    assert [reply[0] for reply in send(chain, BROADCAST_ID, Instruction.PING)] == [1, 2, 3]


def test_broadcast_write_executes_everywhere_without_reply(three: DynamixelChain) -> None:
    assert send(three, BROADCAST_ID, Instruction.WRITE, u16(563) + b"\x2a") == []
    assert [three.device(i).item("LED Red") for i in (1, 2, 3)] == [42, 42, 42]


def test_sync_read_in_listed_order_and_stops_at_a_missing_id(three: DynamixelChain) -> None:
    for i in (1, 2, 3):
        three.device(i).set_item("Present Position", 100 * i)
    replies = send(three, BROADCAST_ID, Instruction.SYNC_READ, u16(611) + u16(4) + b"\x03\x01\x02")
    assert [(r[0], r[2]) for r in replies] == [(3, s32(300)), (1, s32(100)), (2, s32(200))]
    replies = send(three, BROADCAST_ID, Instruction.SYNC_READ, u16(611) + u16(4) + b"\x01\x09\x02")
    assert [r[0] for r in replies] == [1]  # ID 9 is absent: ID 2 waits for it forever
    three.faults.silent_ids = {2}
    replies = send(three, BROADCAST_ID, Instruction.SYNC_READ, u16(611) + u16(4) + b"\x01\x02\x03")
    assert [r[0] for r in replies] == [1]


def test_bulk_read_and_bulk_write(three: DynamixelChain) -> None:
    params = b"\x01" + u16(596) + u16(4) + s32(-99) + b"\x03" + u16(563) + u16(1) + b"\x07"
    assert send(three, BROADCAST_ID, Instruction.BULK_WRITE, params) == []
    assert three.device(1).item("Goal Position") == -99
    assert three.device(3).item("LED Red") == 7
    query = b"\x03" + u16(563) + u16(1) + b"\x01" + u16(596) + u16(4)
    replies = send(three, BROADCAST_ID, Instruction.BULK_READ, query)
    assert [(r[0], r[2]) for r in replies] == [(3, b"\x07"), (1, s32(-99))]


def test_malformed_sync_write_is_ignored(three: DynamixelChain) -> None:
    params = u16(563) + u16(1) + b"\x01\x05\x02"  # second entry lacks its data byte
    assert send(three, BROADCAST_ID, Instruction.SYNC_WRITE, params) == []
    assert three.device(1).item("LED Red") == 0


def test_wire_model_due_times() -> None:
    """Instruction wire time, then per device: its Return Delay Time and its reply's wire
    time, one after the other (10 bits per byte)."""
    devices = [H54Device(1), H54Device(2, eeprom_overrides={"Return Delay Time": 10})]
    chain = DynamixelChain(devices)
    baud = 1_000_000
    bit_s = 10 / baud
    (reply,) = send(chain, 1, Instruction.READ, u16(611) + u16(4), now_s=5.0, line_baud_bps=baud)
    assert reply[3] == pytest.approx(5.0 + 14 * bit_s + 250 * 2e-6 + 15 * bit_s)
    replies = send(
        chain, BROADCAST_ID, Instruction.SYNC_READ, u16(611) + u16(4) + b"\x01\x02",
        now_s=5.0, line_baud_bps=baud,
    )  # fmt: skip
    first = 5.0 + 16 * bit_s + 500e-6 + 15 * bit_s
    assert replies[0][3] == pytest.approx(first)
    assert replies[1][3] == pytest.approx(first + 20e-6 + 15 * bit_s)
    # without a known line speed each device's own Baud Rate (57,600 by default) times it
    (reply,) = send(chain, 1, Instruction.PING, now_s=0.0)
    assert reply[3] == pytest.approx(10 * 10 / 57_600 + 500e-6 + 14 * 10 / 57_600)


def test_enforce_baud_silences_a_device_at_another_speed() -> None:
    chain = DynamixelChain([H54Device(1, baud_index=6)], enforce_baud=True)
    assert send(chain, 1, Instruction.PING, line_baud_bps=1_000_000) == []
    assert len(send(chain, 1, Instruction.PING, line_baud_bps=4_000_000)) == 1
    assert len(send(chain, 1, Instruction.PING, line_baud_bps=None)) == 1  # speed unknown


def test_line_faults() -> None:
    faults = LineFaults(drop_reply_ids={1})
    chain = DynamixelChain([H54Device(1), H54Device(2)], faults=faults)
    replies = send(chain, BROADCAST_ID, Instruction.SYNC_READ, u16(611) + u16(4) + b"\x01\x02")
    assert [r[0] for r in replies] == [1 + 1]  # ID 1's reply lost on the way, ID 2 answered
    faults.clear()
    faults.corrupt_next_replies = 1
    raw = chain.handle(build_instruction_packet(1, Instruction.PING), 0.0)
    assert not parse_packet(raw[0][1]).crc_ok
    assert faults.corrupt_next_replies == 0
    assert parse_packet(
        chain.handle(build_instruction_packet(1, Instruction.PING), 0.0)[0][1]
    ).crc_ok
    faults.drop_next_replies = 2
    assert send(chain, 1, Instruction.PING) == [] and send(chain, 2, Instruction.PING) == []
    assert len(send(chain, 1, Instruction.PING)) == 1
    faults.silent_ids = {1}
    assert send(chain, 1, Instruction.WRITE, u16(563) + b"\x01") == []
    assert chain.device(1).item("LED Red") == 0  # unplugged: not executed either


def test_tick_listener_runs_before_each_instruction(one: DynamixelChain) -> None:
    seen = []
    one.add_tick_listener(seen.append)
    send(one, 1, Instruction.PING, now_s=3.5)
    assert seen == [3.5]


def test_constructor_and_firmware_api_errors() -> None:
    with pytest.raises(ValueError, match="RAM"):
        H54Device(1, eeprom_overrides={"Goal Position": 0})
    with pytest.raises(KeyError, match="e-Manual"):
        H54Device(1, eeprom_overrides={"goal_position": 0})
    with pytest.raises(ValueError, match="outside its range"):
        H54Device(1, eeprom_overrides={"Baud Rate": 9})
    with pytest.raises(ValueError, match="ID must be"):
        H54Device(253)
    with pytest.raises(ValueError, match="does not fit"):
        H54Device(1).set_item("Present Position", 2**31)
    with pytest.raises(ValueError, match="share ID"):
        DynamixelChain([H54Device(1), H54Device(1)])
    with pytest.raises(KeyError, match="IDs present"):
        DynamixelChain([H54Device(1)]).device(2)
    device = H54Device(4, eeprom_overrides={"Model Number": 1234})
    assert device.item("Model Number") == 1234
