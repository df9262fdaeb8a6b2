"""Faults through DynamixelChain against the emulated H54 chain (separate process, unmodified
dynamixel-sdk): hardware errors / shutdown, reboot, silent and lost replies and what they cost,
best-effort disable."""

from __future__ import annotations

import statistics
import time

import numpy as np
import pytest

from drivers.dynamixel import (
    DeviceShutdownError,
    DynamixelChain,
    DynamixelChainConfig,
    DynamixelJointConfig,
    HardwareError,
)
from drivers.joint_bus import BusError
from sim_backend.dynamixel.testing import spawn_emulated_chain
from tests.support.load_conditions import FUNCTIONAL_LATENCY_TIMER_MS, timing_is_unreliable

pytestmark = pytest.mark.timeout(60)

BAUD_4M = 4_000_000
OVERLOAD = int(HardwareError.OVERLOAD)  # 0x20, in the default Shutdown mask 58
OVERHEATING = int(HardwareError.OVERHEATING)  # 0x04, not in the default Shutdown mask
# The emulator runs in another process on a 2-core VM shared with other work: its replies
# usually take ~0.1 ms, but while other processes compete (and it has no real-time scheduling)
# it is descheduled for tens of milliseconds now and then. Functional tests therefore use a
# generous reply timeout (~150 ms, tests/load_conditions.py); only the timing tests use the
# production latency of 1 ms.
TEST_LATENCY_TIMER_MS = FUNCTIONAL_LATENCY_TIMER_MS  # tests/load_conditions.py
# Timing tests: the production setting (USB latency timer 1 ms, as ROBOTIS advise).
PRODUCTION_LATENCY_TIMER_MS = 1.0


def make_config(
    port: str,
    ids: tuple[int, ...],
    latency_timer_ms: float = TEST_LATENCY_TIMER_MS,
    **joint_kw: object,
) -> DynamixelChainConfig:
    joints = tuple(
        DynamixelJointConfig(dxl_id=i, min_position_rad=-1.0, max_position_rad=1.0, **joint_kw)  # type: ignore[arg-type]
        for i in ids
    )
    return DynamixelChainConfig(
        port=port, baudrate=BAUD_4M, joints=joints, latency_timer_ms=latency_timer_ms
    )


def test_hardware_error_reaches_read_state_and_reboot_clears_it() -> None:
    with (
        spawn_emulated_chain(ids=(1, 2)) as emu,
        DynamixelChain(make_config(emu.port_path, (1, 2))) as chain,
    ):
        chain.enable()
        chain.write_goals(np.array([0.2, 0.1]))
        assert chain.read_state().torque_enabled.all()
        emu.raise_hardware_error(1, OVERLOAD)
        state = chain.read_state()  # the very next read
        assert state.all_valid  # a status with the Alert bit still carries data
        assert state.hardware_error.tolist() == [OVERLOAD, 0]
        assert state.torque_enabled.tolist() == [False, True]
        assert state.alert.tolist() == [True, False]
        status = chain.read_hardware_error(1)
        assert (status.bits, status.alert, status.describe()) == (OVERLOAD, True, "OVERLOAD")
        with pytest.raises(DeviceShutdownError, match=r"ID 1: .*0x20 \(OVERLOAD\).*REBOOT") as e:
            chain.enable()
        assert e.value.hardware_errors == {1: OVERLOAD}
        assert emu.item(1, "Torque Enable") == 0  # the refusal did not touch the device
        after_reboot = chain.reboot([1])
        assert after_reboot[1].bits == 0 and not after_reboot[1].alert
        state = chain.read_state()
        assert state.hardware_error.tolist() == [0, 0] and not state.alert.any()
        assert state.torque_enabled.tolist() == [False, True]  # reboot leaves torque off
        chain.enable([1])
        state = chain.read_state()
        assert state.torque_enabled.all()
        assert state.position_rad[0] == pytest.approx(0.2, abs=1e-5)  # no jump


def test_hardware_error_outside_the_shutdown_mask_keeps_torque_but_is_reported() -> None:
    with (
        spawn_emulated_chain(ids=(1,)) as emu,
        DynamixelChain(make_config(emu.port_path, (1,))) as chain,
    ):
        chain.enable()
        emu.raise_hardware_error(1, OVERHEATING)
        state = chain.read_state()
        assert state.hardware_error[0] == OVERHEATING and state.alert[0]
        assert state.torque_enabled[0]  # Overheating is not in the default Shutdown (58)
        with pytest.raises(DeviceShutdownError, match="OVERHEATING"):
            chain.enable()  # a latched hardware error: refuse until rebooted


def test_enable_reports_a_shutdown_latch_the_device_itself_enforces() -> None:
    with (
        spawn_emulated_chain(ids=(1,)) as emu,
        DynamixelChain(make_config(emu.port_path, (1,))) as chain,
    ):
        emu.raise_hardware_error(1, OVERLOAD)
        emu.clear_hardware_error(1, OVERLOAD)  # the status bit is gone, the shutdown latch not
        assert chain.read_hardware_error(1).bits == 0
        with pytest.raises(DeviceShutdownError, match=r"ID 1 refused Torque Enable = 1.*REBOOT"):
            chain.enable()
        assert emu.item(1, "Torque Enable") == 0
        chain.reboot()
        chain.enable()
        assert emu.item(1, "Torque Enable") == 1


def test_reboot_reapplies_ram_settings() -> None:
    with spawn_emulated_chain(ids=(1, 2)) as emu:
        config = make_config(emu.port_path, (1, 2), position_p_gain=45)
        with DynamixelChain(config) as chain:
            assert emu.item(2, "Position P Gain") == 45
            chain.reboot()
            assert emu.item(2, "Position P Gain") == 45  # RAM: default again, then re-applied
            assert chain.read_state().all_valid


def test_reboot_waits_a_bounded_time_for_a_device_that_does_not_come_back() -> None:
    with spawn_emulated_chain(ids=(1,), reboot_time_s=2.0) as emu:
        config = DynamixelChainConfig(
            port=emu.port_path,
            baudrate=BAUD_4M,
            joints=make_config(emu.port_path, (1,)).joints,
            latency_timer_ms=TEST_LATENCY_TIMER_MS,
            reboot_timeout_s=0.2,
        )
        with DynamixelChain(config) as chain:
            start = time.perf_counter()
            with pytest.raises(BusError, match=r"ID 1 did not answer PING within reboot_timeout"):
                chain.reboot()
            assert time.perf_counter() - start < 0.2 + 0.2

    with (
        spawn_emulated_chain(ids=(1,)) as emu,
        DynamixelChain(make_config(emu.port_path, (1,))) as chain,
    ):
        emu.set_silenced(1)
        with pytest.raises(BusError, match="ID 1: REBOOT failed"):
            chain.reboot()


def _timed_reads(chain: DynamixelChain, count: int) -> tuple[list[float], list]:
    durations, states = [], []
    for _ in range(count):
        start = time.perf_counter()
        states.append(chain.read_state())
        durations.append(time.perf_counter() - start)
    return durations, states


def test_silent_id_in_the_middle_invalidates_it_and_the_ids_after_it() -> None:
    with (
        spawn_emulated_chain(ids=(1, 2, 3)) as emu,
        DynamixelChain(make_config(emu.port_path, (1, 2, 3))) as chain,
    ):
        before = chain.read_state()
        emu.faults(silent_ids={2})
        silent = chain.read_state()
        emu.clear_faults()
        recovered = chain.read_state()
    assert before.all_valid
    # Devices after a silent one wait for it and stay silent too (DynamixelSDK #364).
    assert silent.valid.tolist() == [True, False, False]
    assert np.isnan(silent.position_rad[1:]).all() and np.isnan(silent.current_a[1:]).all()
    assert silent.position_rad[0] == before.position_rad[0]
    assert not silent.torque_enabled[1:].any() and not silent.hardware_error[1:].any()
    assert silent.errors == [
        "ID 2: no valid sync-read reply (timeout)",
        "ID 3: no valid sync-read reply (timeout)",
    ]
    assert recovered.all_valid and recovered.errors == []


@pytest.mark.timing
@pytest.mark.parametrize("n_devices", [3, 12])
def test_a_silent_id_costs_one_bounded_timeout(n_devices: int) -> None:
    ids = tuple(range(1, n_devices + 1))
    silent = ids[-1]
    with (
        spawn_emulated_chain(ids=ids) as emu,
        DynamixelChain(make_config(emu.port_path, ids)) as chain,
    ):
        # Open (and warm the fresh emulator up) with the generous timeout, measure with the
        # production one.
        chain.port_handler.latency_timer_ms = PRODUCTION_LATENCY_TIMER_MS
        timeout_ms = chain.port_handler.packet_timeout_ms((11 + 15) * n_devices)
        healthy_s, _ = _timed_reads(chain, 50)
        emu.faults(silent_ids={silent})
        silent_s, states = _timed_reads(chain, 50)
        reason = timing_is_unreliable(bool(emu.stats()["sched_fifo"]), client_spins=True)
    for state in states:
        assert not state.valid[-1] and np.isnan(state.position_rad[-1])
    healthy_ms = 1e3 * statistics.median(healthy_s)
    silent_ms = 1e3 * statistics.median(silent_s)
    print(
        f"\n{n_devices} IDs, ID {silent} silent: read_state median {silent_ms:.2f} ms "
        f"(max {1e3 * max(silent_s):.2f}), healthy {healthy_ms:.3f} ms; packet timeout "
        f"{timeout_ms:.3f} ms with latency_timer_ms={PRODUCTION_LATENCY_TIMER_MS}"
    )
    # One timeout for the whole group: (11 + 15) x N bytes x 2.5 us + 2 x 1 ms + 2 ms.
    assert timeout_ms == pytest.approx(26 * n_devices * 0.0025 + 4.0)
    # It costs that timeout (it cannot end earlier), plus scheduling delay on a busy machine;
    # the bound stays far below the SDK's own >= 34 ms per call (relaxed, and said why, when
    # the machine is loaded: the SDK busy-waits, so the client competes for a CPU).
    slack_ms = 10.0 if reason is None else 100.0
    assert timeout_ms * 0.95 <= silent_ms <= timeout_ms + slack_ms, reason


def test_a_lost_or_corrupted_reply_costs_only_that_device() -> None:
    with (
        spawn_emulated_chain(ids=(1, 2, 3)) as emu,
        DynamixelChain(make_config(emu.port_path, (1, 2, 3))) as chain,
    ):
        emu.faults(drop_reply_ids={2})
        dropped = chain.read_state()
        emu.clear_faults()
        emu.faults(corrupt_crc_ids={2})
        corrupted = chain.read_state()
        emu.clear_faults()
        healthy = chain.read_state()
    assert dropped.valid.tolist() == [True, False, True]
    assert np.isnan(dropped.position_rad[1]) and not np.isnan(dropped.position_rad[[0, 2]]).any()
    assert dropped.errors == ["ID 2: no valid sync-read reply (timeout)"]
    assert corrupted.valid.tolist() == [True, False, True]
    assert corrupted.errors == ["ID 2: no valid sync-read reply (1 corrupt reply(s) received)"]
    assert healthy.all_valid and healthy.errors == []


def test_disable_is_best_effort() -> None:
    with (
        spawn_emulated_chain(ids=(1, 2, 3)) as emu,
        DynamixelChain(make_config(emu.port_path, (1, 2, 3))) as chain,
    ):
        chain.enable()
        emu.faults(silent_ids={2})
        with pytest.raises(BusError, match=r"could not turn torque off.*ID 2") as raised:
            chain.disable()
        assert "ID 1" not in str(raised.value) and "ID 3" not in str(raised.value)
        assert [emu.item(i, "Torque Enable") for i in (1, 2, 3)] == [0, 1, 0]
        emu.clear_faults()
        emu.raise_hardware_error(2, OVERLOAD)  # a device in shutdown: disable still fine
        chain.disable()
        assert emu.item(2, "Torque Enable") == 0
