"""The 200 Hz path of DynamixelChain against the emulated H54 chain (separate process,
unmodified dynamixel-sdk): one sync read of the indirect state block, units, one sync write of
goals, goal checks before sending, enable without a jump."""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import pytest

from drivers.dynamixel import DynamixelChain, DynamixelChainConfig, DynamixelJointConfig
from drivers.joint_bus import BusError
from sim_backend.dynamixel.testing import EmulatedChain, spawn_emulated_chain
from tests.support.load_conditions import FUNCTIONAL_LATENCY_TIMER_MS

pytestmark = pytest.mark.timeout(60)

BAUD_4M = 4_000_000  # emulator baud_index 6
# The emulator runs in another process on a 2-core VM shared with other work: its replies
# usually take ~0.1 ms, but while other processes compete (and it has no real-time scheduling)
# it is descheduled for tens of milliseconds now and then. Functional tests therefore use a
# generous reply timeout (~150 ms, tests/load_conditions.py); only the timing tests use the
# production latency of 1 ms.
TEST_LATENCY_TIMER_MS = FUNCTIONAL_LATENCY_TIMER_MS  # tests/load_conditions.py
RAD_PER_PULSE = 2 * math.pi / 501_923  # e-Manual: 501,923 pulse/rev
RAD_S_PER_UNIT = 0.00199234 * 2 * math.pi / 60  # 0.00199234 rpm
AMPERE_PER_UNIT = 33.0 / 2048.0  # 16.11328 mA
STATE_BLOCK_BYTES = 15
SYNC_READ_INSTRUCTION_BYTES = 14  # header 7 + inst 1 + addr 2 + len 2 + CRC 2, + 1 per ID
STATUS_OVERHEAD_BYTES = 11  # header 7 + inst 1 + err 1 + CRC 2


def joint(dxl_id: int, **overrides: object) -> DynamixelJointConfig:
    fields: dict[str, object] = {"dxl_id": dxl_id, "min_position_rad": -1.0}
    fields.update({"max_position_rad": 1.0, **overrides})
    return DynamixelJointConfig(**fields)  # type: ignore[arg-type]


@contextmanager
def emulated(
    joints: tuple[DynamixelJointConfig, ...], firmware: str
) -> Iterator[tuple[EmulatedChain, DynamixelChain]]:
    """An emulated chain of these joints' IDs (separate process) and an open driver on it."""
    ids = tuple(j.dxl_id for j in joints)
    with (
        spawn_emulated_chain(ids=ids, firmware=firmware) as emu,
        DynamixelChain(make_config(emu.port_path, joints)) as chain,
    ):
        yield emu, chain


def make_config(port: str, joints: tuple[DynamixelJointConfig, ...]) -> DynamixelChainConfig:
    return DynamixelChainConfig(
        port=port, baudrate=BAUD_4M, joints=joints, latency_timer_ms=TEST_LATENCY_TIMER_MS
    )


@pytest.mark.parametrize("n_devices", [1, 12])
def test_state_block_arrives_in_one_sync_read(n_devices: int) -> None:
    ids = tuple(range(1, n_devices + 1))
    joints = tuple(joint(i, direction=-1 if i % 2 else 1, offset_rad=0.01 * i) for i in ids)
    with spawn_emulated_chain(ids=ids, firmware="none") as emu:
        for i in ids:
            emu.set_item(i, "Present Position", 1000 * i - 5000)
            emu.set_item(i, "Present Velocity", -37 * i)
            emu.set_item(i, "Present Current", 20 * i - 100)
            emu.set_item(i, "Present Input Voltage", 230 + i)
            emu.set_item(i, "Present Temperature", 30 + i)
        with DynamixelChain(make_config(emu.port_path, joints)) as chain:
            before = emu.stats()
            state = chain.read_state()
            after = emu.stats()
            # Exactly one SYNC_READ went out and every device answered it once with 15 bytes.
            assert after["bytes_in"] - before["bytes_in"] == SYNC_READ_INSTRUCTION_BYTES + n_devices
            assert after["replies_sent"] - before["replies_sent"] == n_devices
            assert after["bytes_out"] - before["bytes_out"] == n_devices * (
                STATUS_OVERHEAD_BYTES + STATE_BLOCK_BYTES
            )
    assert state.errors == [] and state.all_valid and state.dxl_ids == ids
    for index, i in enumerate(ids):
        direction = -1 if i % 2 else 1
        expected_rad = direction * ((1000 * i - 5000) * RAD_PER_PULSE - 0.01 * i)
        assert state.position_rad[index] == pytest.approx(expected_rad, abs=1e-12)
        assert state.velocity_rad_s[index] == pytest.approx(direction * -37 * i * RAD_S_PER_UNIT)
        assert state.current_a[index] == pytest.approx(direction * (20 * i - 100) * AMPERE_PER_UNIT)
        assert state.torque_estimate_nm[index] == pytest.approx(state.current_a[index] * 44.7 / 9.3)
        assert state.input_voltage_v[index] == pytest.approx(0.1 * (230 + i))
        assert state.temperature_c[index] == 30 + i
    assert not state.torque_enabled.any() and not state.alert.any()
    assert state.hardware_error.dtype == np.uint8 and not state.hardware_error.any()


def test_position_units_and_quantisation_step_through_the_bus() -> None:
    with emulated((joint(1),), firmware="none") as (emu, chain):
        emu.set_item(1, "Present Position", 125_481)  # ~ a quarter turn
        quarter = chain.read_state().position_rad[0]
        emu.set_item(1, "Present Position", 125_482)
        next_pulse = chain.read_state().position_rad[0]
        emu.set_item(1, "Present Position", -250_961)
        most_negative = chain.read_state().position_rad[0]
    assert quarter == pytest.approx(math.pi / 2, abs=RAD_PER_PULSE)
    assert quarter == pytest.approx(125_481 * 2 * math.pi / 501_923, rel=1e-15)
    assert next_pulse - quarter == pytest.approx(2 * math.pi / 501_923, rel=1e-9)
    assert math.degrees(most_negative) == pytest.approx(-179.999, abs=1e-3)


def test_goals_go_out_in_one_sync_write_as_exact_pulses() -> None:
    joints = (joint(1), joint(2, direction=-1, offset_rad=0.2), joint(3))
    with emulated(joints, firmware="none") as (emu, chain):
        before = emu.stats()
        chain.write_goals(np.array([0.5, -0.3, -1.0]))
        after = emu.stats()
        goals = [emu.item(i, "Goal Position") for i in (1, 2, 3)]
    # One SYNC_WRITE (14 + 5 x 3 bytes), no reply.
    assert after["bytes_in"] - before["bytes_in"] == 14 + 5 * 3
    assert after["replies_sent"] == before["replies_sent"]
    assert goals[0] == round(0.5 / RAD_PER_PULSE)
    assert goals[1] == round((0.2 + 0.3) / RAD_PER_PULSE)  # device = offset + direction * joint
    assert goals[2] == round(-1.0 / RAD_PER_PULSE)  # the range's end is allowed


def test_goal_outside_the_limits_raises_before_anything_is_sent() -> None:
    joints = (joint(1), joint(2, min_position_rad=-0.2, max_position_rad=0.4))
    with emulated(joints, firmware="none") as (emu, chain):
        chain.write_goals(np.array([0.1, 0.1]))
        before = emu.stats()
        for bad_goal, message in [
            ([0.2, 0.41], r"ID 2: goal 0\.41 rad outside \[-0\.2, 0\.4\]"),
            ([-1.5, 0.0], r"ID 1: goal -1\.5 rad outside"),
            ([math.nan, 0.0], "ID 1: goal nan"),
            ([0.1, math.inf], "ID 2: goal inf"),
        ]:
            with pytest.raises(ValueError, match=message):
                chain.write_goals(np.array(bad_goal))
        with pytest.raises(ValueError, match="one goal per joint"):
            chain.write_goals(np.array([0.1, 0.1, 0.1]))
        after = emu.stats()
        goals = [emu.item(i, "Goal Position") for i in (1, 2)]
    assert after["bytes_in"] == before["bytes_in"]  # not one byte went out
    assert goals == [round(0.1 / RAD_PER_PULSE)] * 2  # the devices kept the last good goal


def test_enable_writes_goal_equal_present_first_then_torque() -> None:
    with emulated((joint(1), joint(2)), firmware="none") as (emu, chain):
        # A stale goal far from where the output is: torque on must not jump to it.
        emu.set_item(1, "Present Position", 40_000)
        emu.set_item(1, "Goal Position", -30_000)
        emu.set_item(2, "Present Position", -12_345)
        emu.set_item(2, "Goal Position", 70_000)
        chain.enable()
        assert [emu.item(i, "Goal Position") for i in (1, 2)] == [40_000, -12_345]
        assert [emu.item(i, "Torque Enable") for i in (1, 2)] == [1, 1]
        state = chain.read_state()
        assert state.torque_enabled.all()
        chain.disable([1])
        assert [emu.item(i, "Torque Enable") for i in (1, 2)] == [0, 1]
        with pytest.raises(ValueError, match=r"IDs \[7\] are not in this chain"):
            chain.enable([7])


def test_enable_refuses_a_joint_outside_its_range() -> None:
    with spawn_emulated_chain(ids=(1,), firmware="none") as emu:
        config = make_config(emu.port_path, (joint(1, max_position_rad=0.5),))
        with DynamixelChain(config) as chain:
            emu.set_item(1, "Present Position", round(0.6 / RAD_PER_PULSE))
            with pytest.raises(BusError, match=r"position 0\.6000 rad is outside the joint range"):
                chain.enable()
            assert emu.item(1, "Torque Enable") == 0


def test_ideal_servo_follows_goals_through_the_driver() -> None:
    with emulated((joint(1), joint(2)), firmware="ideal") as (emu, chain):
        chain.enable()
        goals = np.array([0.3, -0.7])
        chain.write_goals(goals)
        state = chain.read_state()
    np.testing.assert_allclose(state.position_rad, goals, atol=RAD_PER_PULSE / 2)


def test_a_sync_read_left_uncollected_does_not_answer_the_next_transaction() -> None:
    """request_state() and then, without receive_state() (an exception in between), torque off
    and a READ: the chain stays usable, its late sync-read replies (500 us Return Delay Time
    each) taken for nothing else (the chain collects them first, and its reads match replies
    by ID and length besides)."""
    joints = (joint(1), joint(2))
    with (
        spawn_emulated_chain(
            ids=(1, 2),
            firmware="none",
            realtime=True,
            eeprom_overrides={"Return Delay Time": 250},
        ) as emu,
        DynamixelChain(make_config(emu.port_path, joints)) as chain,
    ):
        chain.enable()
        for _ in range(5):
            chain.request_state()
            chain.disable([1])
            assert emu.item(1, "Torque Enable") == 0
            assert chain.read_hardware_error(1).bits == 0
            state = chain.read_state()
            assert state.valid.all(), state.errors
            assert list(state.torque_enabled) == [False, True]
            chain.enable([1])
