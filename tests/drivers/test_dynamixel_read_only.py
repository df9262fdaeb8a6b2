"""DynamixelChain.open(read_only=True) on the emulated chain: it reads the state, writes nothing
(not even the EEPROM configuration a normal open writes), and refuses every command."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.dynamixel import DynamixelChain, DynamixelChainConfig, DynamixelJointConfig
from drivers.dynamixel.hardware_error import HardwareError
from drivers.joint_bus import BusError
from sim_backend.dynamixel.testing import spawn_emulated_chain

pytestmark = pytest.mark.timeout(60)

BAUD_4M = 4_000_000
LATENCY_MS = 20.0  # generous, as in test_dynamixel_open.py: the emulator is another process
# Items a normal open() writes on a factory device, and the ones a run commands.
WATCHED_ITEMS = (
    "Torque Enable",
    "Goal Position",
    "Return Delay Time",
    "Max Position Limit",
    "Min Position Limit",
    "Indirect Address 1",
    "Status Return Level",
)


def _config(port: str) -> DynamixelChainConfig:
    joints = (
        DynamixelJointConfig(
            dxl_id=1, direction=-1, offset_rad=0.25, min_position_rad=-0.5, max_position_rad=1.5
        ),
        DynamixelJointConfig(dxl_id=2, min_position_rad=-1.0, max_position_rad=1.0),
    )
    return DynamixelChainConfig(
        port=port, baudrate=BAUD_4M, joints=joints, latency_timer_ms=LATENCY_MS
    )


def _watched(emu, ids=(1, 2)) -> dict[tuple[int, str], int]:
    return {(i, name): emu.item(i, name) for i in ids for name in WATCHED_ITEMS}


@pytest.mark.parametrize("mapped", [False, True], ids=["factory", "configured"])
def test_read_only_open_reads_the_state_and_writes_nothing(mapped: bool) -> None:
    with spawn_emulated_chain(ids=(1, 2)) as emu:
        config = _config(emu.port_path)
        if mapped:  # a chain a run has configured before: the state-block map is in place
            with DynamixelChain(config):
                pass
        rad = config.spec.units.rad_per_pulse
        emu.set_item(1, "Present Position", 40_000)
        emu.set_item(2, "Present Position", -12_345)
        emu.set_item(1, "Present Temperature", 41)
        emu.set_item(2, "Present Input Voltage", 243)  # 24.3 V (0.1 V units)
        before = _watched(emu)
        chain = DynamixelChain(config)
        chain.open(read_only=True)
        try:
            state = chain.read_state()
            assert state.valid.all(), state.errors
            # joint = direction * (device - offset), the device's angle = pulses * rad/pulse
            assert state.position_rad[0] == pytest.approx(-(40_000 * rad - 0.25), abs=1e-12)
            assert state.position_rad[1] == pytest.approx(-12_345 * rad, abs=1e-12)
            assert state.temperature_c[0] == 41
            assert state.input_voltage_v[1] == pytest.approx(24.3)
            assert not state.torque_enabled.any()
            assert (state.hardware_error == 0).all()
            factory_changes = [device.eeprom_changes for device in chain.devices]
            assert all(factory_changes) != mapped  # what a normal open would write, unwritten
            for command in (
                lambda: chain.write_goals(np.zeros(2)),
                chain.enable,
                chain.disable,
                chain.reboot,
            ):
                with pytest.raises(BusError, match="read-only"):
                    command()
        finally:
            chain.close()
        assert _watched(emu) == before


def test_read_only_span_read_reports_a_latched_hardware_error() -> None:
    """Without the state-block map the span does not hold Hardware Error Status: the Alert bit
    of the reply leads to it."""
    with spawn_emulated_chain(ids=(1, 2)) as emu:
        chain = DynamixelChain(_config(emu.port_path))
        chain.open(read_only=True)
        try:
            assert chain.read_state().hardware_error.tolist() == [0, 0]
            emu.raise_hardware_error(2, HardwareError.OVERLOAD)
            state = chain.read_state()
            assert state.valid.all(), state.errors
            assert state.hardware_error.tolist() == [0, int(HardwareError.OVERLOAD)]
            assert state.alert.tolist() == [False, True]
        finally:
            chain.close()
