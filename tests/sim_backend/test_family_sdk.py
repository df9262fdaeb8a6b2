"""Every model of the DYNAMIXEL PRO family on the emulator, driven by ROBOTIS's unmodified
dynamixel-sdk through a pty: PING answers the model's number, every register the driver uses
reads at the address and size the driver's table (written on its own from the e-Manual) gives,
and writes meet the model's own ranges and rules.

One emulator process serves the whole family (model i at ID i + 1), so that the 22 cases cost
one start.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from dynamixel_sdk import COMM_SUCCESS, PacketHandler, PortHandler

from drivers.dynamixel import MODELS, REGISTERS, ModelSpec, model_number
from sim_backend.dynamixel.models import FAMILY
from sim_backend.dynamixel.testing import EmulatedChain, spawn_emulated_chain

pytestmark = pytest.mark.timeout(120)

NAMES = [m.name for m in FAMILY]
IDS = {name: index + 1 for index, name in enumerate(NAMES)}
DATA_RANGE, DATA_LIMIT, ACCESS = 4, 6, 7  # Protocol 2.0 status error numbers


@pytest.fixture(scope="module")
def family() -> Iterator[tuple[EmulatedChain, PortHandler, PacketHandler]]:
    with spawn_emulated_chain(
        ids=tuple(IDS.values()),
        models={dxl_id: name for name, dxl_id in IDS.items()},
        firmware="none",
    ) as emu:
        port = PortHandler(emu.port_path)
        assert port.openPort()
        try:
            yield emu, port, PacketHandler(2.0)
        finally:
            port.closePort()


def _read(packet: PacketHandler, port: PortHandler, dxl_id: int, address: int, size: int) -> int:
    reader = {1: packet.read1ByteTxRx, 2: packet.read2ByteTxRx, 4: packet.read4ByteTxRx}[size]
    value, result, error = reader(port, dxl_id, address)
    assert (result, error) == (COMM_SUCCESS, 0), (address, size, result, error)
    return value


def _write(packet: PacketHandler, port: PortHandler, dxl_id: int, item: object, value: int) -> int:
    """WRITE of a driver item; returns the status error number."""
    data = value.to_bytes(item.size, "little", signed=item.signed)
    result, error = packet.writeTxRx(port, dxl_id, item.address, item.size, list(data))
    assert result == COMM_SUCCESS
    return error & 0x7F


@pytest.mark.parametrize("name", NAMES)
def test_the_sdk_pings_reads_and_writes_each_model_as_its_table_says(
    family: tuple[EmulatedChain, PortHandler, PacketHandler], name: str
) -> None:
    emu, port, packet = family
    dxl_id = IDS[name]
    spec: ModelSpec = MODELS[model_number(name)]  # the driver's table of this model
    number, result, error = packet.ping(port, dxl_id)
    assert (number, result, error) == (spec.model_number, COMM_SUCCESS, 0)
    # every register the driver uses is where, and as wide as, the driver's table says
    for register in REGISTERS:
        item = spec.item(register)
        _read(packet, port, dxl_id, item.address, item.size)
    assert _read(packet, port, dxl_id, 0, 2) == spec.model_number
    # the current cap: the top of its range is accepted, one more refused (Data Range)
    cap = spec.item("Torque Limit")
    initial = _read(packet, port, dxl_id, cap.address, cap.size)
    assert _write(packet, port, dxl_id, cap, spec.torque_limit_max_raw) == 0
    assert _write(packet, port, dxl_id, cap, spec.torque_limit_max_raw + 1) == DATA_RANGE
    assert _write(packet, port, dxl_id, cap, initial) == 0
    # Goal Position is bounded by Max Position Limit in position mode (Data Limit)
    top = _read(packet, port, dxl_id, spec.item("Max Position Limit").address, 4)
    goal = spec.item("Goal Position")
    assert 0 < top <= spec.units.position_limit_pulses
    assert _write(packet, port, dxl_id, goal, top) == 0
    assert _write(packet, port, dxl_id, goal, top + 1) == DATA_LIMIT
    assert emu.item(dxl_id, "Goal Position") == top
    # EEPROM is locked while torque is on (Access), open again once it is off
    torque, delay = spec.item("Torque Enable"), spec.item("Return Delay Time")
    assert _write(packet, port, dxl_id, torque, 1) == 0
    assert _write(packet, port, dxl_id, delay, 0) == ACCESS
    assert _write(packet, port, dxl_id, torque, 0) == 0
    assert _write(packet, port, dxl_id, delay, 0) == 0
    assert _read(packet, port, dxl_id, delay.address, 1) == 0
    # a gain register takes the model's range, no more
    gain = spec.item("Position P Gain")
    assert _write(packet, port, dxl_id, gain, spec.gain_max_raw) == 0
    if spec.gain_max_raw < 65_535:
        assert _write(packet, port, dxl_id, gain, spec.gain_max_raw + 1) == DATA_RANGE


def test_broadcast_ping_answers_every_model_with_its_number(
    family: tuple[EmulatedChain, PortHandler, PacketHandler],
) -> None:
    _, port, packet = family
    answers, result = packet.broadcastPing(port)
    assert result == COMM_SUCCESS
    assert {dxl_id: answers[dxl_id][0] for dxl_id in answers} == {
        IDS[name]: model_number(name) for name in NAMES
    }
