"""DynamixelChain.open()/close() against the emulated H54 chain (separate process, unmodified
dynamixel-sdk on the host side): identification, refusals, EEPROM configuration rules."""

from __future__ import annotations

import pytest

from drivers.dynamixel import (
    DynamixelChain,
    DynamixelChainConfig,
    DynamixelJointConfig,
    EepromChangeRefused,
)
from drivers.joint_bus import BusError
from sim_backend.dynamixel.testing import spawn_emulated_chain
from tests.support.load_conditions import FUNCTIONAL_LATENCY_TIMER_MS

pytestmark = pytest.mark.timeout(60)

BAUD_4M = 4_000_000  # emulator baud_index 6
# The emulator runs in another process on a 2-core VM shared with other work: its replies
# usually take ~0.1 ms, but while other processes compete (and it has no real-time scheduling)
# it is descheduled for tens of milliseconds now and then. Functional tests therefore use a
# generous reply timeout (~150 ms, tests/load_conditions.py); only the timing tests use the
# production latency of 1 ms.
TEST_LATENCY_TIMER_MS = FUNCTIONAL_LATENCY_TIMER_MS  # tests/load_conditions.py


def make_config(port: str, ids: tuple[int, ...], **overrides: object) -> DynamixelChainConfig:
    joints = tuple(
        DynamixelJointConfig(dxl_id=dxl_id, min_position_rad=-1.0, max_position_rad=1.0)
        for dxl_id in ids
    )
    fields: dict[str, object] = {"port": port, "baudrate": BAUD_4M, "joints": joints}
    fields["latency_timer_ms"] = TEST_LATENCY_TIMER_MS
    fields.update(overrides)
    return DynamixelChainConfig(**fields)  # type: ignore[arg-type]


def test_open_configures_a_factory_chain_then_finds_nothing_to_change() -> None:
    joint_1 = DynamixelJointConfig(
        dxl_id=1,
        direction=-1,
        offset_rad=0.25,
        min_position_rad=-0.5,
        max_position_rad=1.5,
        torque_limit_a=5.0,
        position_p_gain=40,
    )
    joint_2 = DynamixelJointConfig(dxl_id=2, min_position_rad=-1.0, max_position_rad=1.0)
    # Device 1 leaves the factory in extended-position mode with a low Status Return Level.
    overrides = {1: {"Operating Mode": 4}, 2: {}}
    with spawn_emulated_chain(ids=(1, 2), eeprom_overrides=overrides) as emu:
        emu.set_item(1, "Status Return Level", 1)
        config = DynamixelChainConfig(
            port=emu.port_path,
            baudrate=BAUD_4M,
            joints=(joint_1, joint_2),
            latency_timer_ms=TEST_LATENCY_TIMER_MS,
        )
        rad_per_pulse = config.spec.units.rad_per_pulse
        with DynamixelChain(config) as chain:
            info = {device.dxl_id: device for device in chain.devices}
            assert info[1].model_number == 54024 and info[1].shutdown_mask == 58
            assert not info[1].torque_enabled and info[1].hardware_error == 0
            assert "Operating Mode 4 -> 3" in info[1].eeprom_changes
            assert "Return Delay Time 250 -> 0" in info[2].eeprom_changes
        # What the devices now hold (firmware-side reads, not through the driver):
        assert emu.item(1, "Operating Mode") == 3 and emu.item(2, "Operating Mode") == 3
        assert emu.item(1, "Return Delay Time") == 0
        assert emu.item(1, "Status Return Level") == 2
        assert emu.item(1, "Position P Gain") == 40
        assert emu.item(1, "Torque Limit") == round(5.0 / (33.0 / 2048.0))  # 310
        # Reversed joint: device range = 0.25 - [1.5, -0.5] rad = [-1.25, 0.75] rad, outwards.
        assert emu.item(1, "Min Position Limit") == int(-1.25 // rad_per_pulse)
        assert emu.item(1, "Max Position Limit") == -int(-0.75 // rad_per_pulse)
        assert emu.item(2, "Max Position Limit") == -int(-1.0 // rad_per_pulse)
        assert emu.item(2, "Torque Limit") == 620  # not configured: left alone
        # The state block's indirect map: entry n holds the address of byte n of the block.
        targets = [*range(611, 619), 621, 622, 623, 624, 892, 562, 625]
        for n, target in enumerate(targets, start=1):
            assert emu.item(2, f"Indirect Address {n}") == target
        with DynamixelChain(config) as chain:
            assert all(device.eeprom_changes == () for device in chain.devices)


def test_missing_id_is_refused_with_a_clear_message() -> None:
    with spawn_emulated_chain(ids=(1, 2)) as emu:
        chain = DynamixelChain(make_config(emu.port_path, (1, 2, 3)))
        with pytest.raises(BusError) as raised:
            chain.open()
        message = str(raised.value)
        assert "ID 3: no answer to PING" in message
        assert "ID 1" not in message and "ID 2" not in message
        assert emu.port_path in message and "4000000 bps" in message
        assert "expected model 54024 (H54-200-S500-R)" in message and "hil scan" in message
        assert not chain.is_open
        # Nothing was configured on the devices that did answer.
        assert emu.item(1, "Return Delay Time") == 250


def test_wrong_model_is_refused_naming_both_models() -> None:
    overrides = {1: {}, 2: {"Model Number": 54025}}  # an H54-200-S500-R(A) at ID 2
    with spawn_emulated_chain(ids=(1, 2), eeprom_overrides=overrides) as emu:
        chain = DynamixelChain(make_config(emu.port_path, (1, 2)))
        with pytest.raises(BusError, match=r"ID 2: found model 54025 \(H54-200-S500-R\(A\)\), "
                           r"expected 54024 \(H54-200-S500-R\)"):  # fmt: skip
            chain.open()
        assert not chain.is_open


def test_eeprom_change_with_torque_on_is_refused_unless_allowed() -> None:
    with spawn_emulated_chain(ids=(1, 2), eeprom_overrides={"Return Delay Time": 0}) as emu:
        config = make_config(emu.port_path, (1, 2))
        # First open: configure both (torque off), then turn torque on at ID 2 only.
        with DynamixelChain(config) as chain:
            chain.enable([2])
        assert emu.item(2, "Torque Enable") == 1
        # An open that needs no EEPROM change does not care about torque and keeps it on.
        with DynamixelChain(config) as chain:
            assert chain.devices[1].torque_enabled
        assert emu.item(2, "Torque Enable") == 1
        # A new range needs new EEPROM limits: refused, nothing written, torque still on.
        narrower = DynamixelChainConfig(
            port=emu.port_path,
            baudrate=BAUD_4M,
            latency_timer_ms=TEST_LATENCY_TIMER_MS,
            joints=tuple(
                DynamixelJointConfig(dxl_id=i, min_position_rad=-0.5, max_position_rad=0.5)
                for i in (1, 2)
            ),
        )
        limit_before = emu.item(2, "Max Position Limit")
        chain = DynamixelChain(narrower)
        with pytest.raises(EepromChangeRefused, match=r"ID 2 needs Max Position Limit") as raised:
            chain.open()
        assert "ID 1" not in str(raised.value)  # torque off there: not the problem
        assert "allow_torque_off=True" in str(raised.value)
        assert not chain.is_open
        assert emu.item(2, "Torque Enable") == 1
        assert emu.item(2, "Max Position Limit") == limit_before
        assert emu.item(1, "Max Position Limit") == limit_before  # nothing written anywhere
        # Allowed: torque goes off (and stays off), the limits are written.
        chain.open(allow_torque_off=True)
        try:
            assert not chain.devices[1].torque_enabled
        finally:
            chain.close()
        assert emu.item(2, "Torque Enable") == 0
        assert emu.item(2, "Max Position Limit") < limit_before


def test_open_close_rules_and_the_sdk_baud_whitelist() -> None:
    with spawn_emulated_chain(ids=(1,)) as emu:
        chain = DynamixelChain(make_config(emu.port_path, (1,)))
        with pytest.raises(BusError, match="not open"):
            chain.read_state()
        chain.open()
        with pytest.raises(BusError, match="already open"):
            chain.open()
        chain.close()
        chain.close()  # safe twice
        assert not chain.is_open
        with pytest.raises(BusError, match="not open"):
            chain.enable()
        # The H54 runs at 4.5 Mbps, the SDK's PortHandler cannot set it.
        fast = DynamixelChain(make_config(emu.port_path, (1,), baudrate=4_500_000))
        with pytest.raises(BusError, match="4500000 bps cannot be set through dynamixel-sdk"):
            fast.open()
