"""A chain that mixes models, driven by `DynamixelChain` over the unmodified dynamixel-sdk
against the emulated family (separate process, pty): identification per ID, the tick path (one
sync read; one sync write per Goal Position address), each device in its own units."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivers.dynamixel import DynamixelChain, DynamixelChainConfig, DynamixelJointConfig
from drivers.dynamixel import model_number as number_of
from drivers.joint_bus import BusError
from sim_backend.dynamixel.testing import spawn_emulated_chain
from tests.support.load_conditions import FUNCTIONAL_LATENCY_TIMER_MS

pytestmark = pytest.mark.timeout(90)

BAUD_4M = 4_000_000
# MANIPULATOR-H's three (legacy PRO) and an (A) revision on the same line
MIXED = {1: "H54-200-S500-R", 2: "H54-100-S500-R", 3: "H42-20-S300-R", 4: "H54-200-S500-R(A)"}
PULSES_PER_REV = {1: 501_923, 2: 501_923, 3: 303_750, 4: 1_003_846}  # e-Manual resolutions


def _config(port: str, models: dict[int, str]) -> DynamixelChainConfig:
    return DynamixelChainConfig(
        port=port,
        baudrate=BAUD_4M,
        joints=tuple(
            DynamixelJointConfig(
                dxl_id=dxl_id,
                model_number=number_of(name),
                min_position_rad=-1.0,
                max_position_rad=1.0,
                name=f"j{dxl_id}",
            )
            for dxl_id, name in models.items()
        ),
        latency_timer_ms=FUNCTIONAL_LATENCY_TIMER_MS,
    )


def test_a_mixed_chain_reads_and_writes_each_device_in_its_own_units() -> None:
    with spawn_emulated_chain(ids=tuple(MIXED), models=MIXED) as emu:
        chain = DynamixelChain(_config(emu.port_path, MIXED))
        chain.open()
        try:
            assert [d.model_name for d in chain.devices] == list(MIXED.values())
            assert [d.model_number for d in chain.devices] == [number_of(n) for n in MIXED.values()]
            chain.enable()
            goals = np.array([0.3, -0.2, 0.5, -0.7])
            before = emu.stats()["replies_sent"]
            chain.write_goals(goals)
            state = chain.read_state()
            replies = emu.stats()["replies_sent"] - before
        finally:
            chain.disable()
            chain.close()
    assert state.all_valid, state.errors
    # one sync read for all four (four replies), each device's goal in its own pulses
    assert replies == 4
    for index, dxl_id in enumerate(MIXED):
        pulse_rad = 2 * math.pi / PULSES_PER_REV[dxl_id]
        assert abs(state.position_rad[index] - goals[index]) <= pulse_rad / 2 + 1e-12
    assert np.all(state.torque_enabled)


def test_goals_of_two_layouts_go_in_one_sync_write_each_and_land_in_the_right_pulses() -> None:
    with spawn_emulated_chain(ids=tuple(MIXED), models=MIXED, firmware="none") as emu:
        chain = DynamixelChain(_config(emu.port_path, MIXED))
        chain.open()
        try:
            # PRO (Goal Position 596) and PRO(A) (564): two groups; one read group for all
            assert sorted(len(group.indices) for group in chain._write_groups) == [1, 3]
            assert len(chain._read_groups) == 1
            chain.enable()
            goals = np.array([0.1, 0.2, 0.3, 0.4])
            chain.write_goals(goals)
            pulses = {dxl_id: emu.item(dxl_id, "Goal Position") for dxl_id in MIXED}
        finally:
            chain.disable()
            chain.close()
    for index, dxl_id in enumerate(MIXED):
        assert pulses[dxl_id] == round(goals[index] * PULSES_PER_REV[dxl_id] / (2 * math.pi))


def test_a_device_of_another_model_than_configured_is_refused_naming_the_model_found() -> None:
    models = {1: "H54-200-S500-R", 2: "H42-20-S300-R"}
    with spawn_emulated_chain(ids=(1, 2), models=models) as emu:
        chain = DynamixelChain(_config(emu.port_path, {1: "H54-200-S500-R", 2: "H54-200-S500-R"}))
        with pytest.raises(
            BusError,
            match=r"ID 2 \(j2\): found model 51200 \(H42-20-S300-R\).*"
            r"configure this joint's model as 'H42-20-S300-R'",
        ):
            chain.open()
        assert not chain.is_open


def test_read_only_on_unmapped_devices_reads_each_models_span() -> None:
    """Without the state-block map (read-only may not write it), each model's own RAM span:
    one sync read per span geometry; a latched error still reaches the caller (PRO: read on the
    Alert bit; PRO+: inside its span)."""
    with spawn_emulated_chain(ids=tuple(MIXED), models=MIXED, firmware="none") as emu:
        emu.set_item(3, "Present Position", 151_875 // 2)  # H42: a quarter turn
        emu.set_item(4, "Present Position", 1_003_846 // 8)  # H54(A): an eighth of a turn
        emu.raise_hardware_error(2, 0x04)  # overheating, not in Shutdown (58): torque stays
        emu.raise_hardware_error(4, 0x01)  # input voltage, not in Shutdown (52)
        chain = DynamixelChain(_config(emu.port_path, MIXED))
        chain.open(read_only=True)
        try:
            assert len(chain._read_groups) == 2  # the PRO span 562..625, the PRO+ 512..594
            state = chain.read_state()
        finally:
            chain.close()
    assert state.all_valid, state.errors
    assert state.position_rad[2] == pytest.approx(math.pi / 2, abs=2e-5)
    assert state.position_rad[3] == pytest.approx(math.pi / 4, abs=1e-5)
    assert list(state.hardware_error) == [0, 0x04, 0, 0x01]
