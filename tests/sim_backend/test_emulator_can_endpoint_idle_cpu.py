"""The CAN keyword arguments the emulator prints must not make a generic client spin a core.

python-can's slcan reads its serial port with the `timeout` keyword as the read timeout; with 0
every waiting reader (canopen's Notifier thread, any recv loop) busy-polls. Here an unmodified
canopen client opens the emulator's SLCAN port with exactly the printed arguments and idles.
"""

from __future__ import annotations

import time

import can
import canopen
import pytest

from sim_backend.server import EmulatedJointSpec, Emulator, EmulatorSpec
from tests.support.load_conditions import timing_is_unreliable

pytestmark = pytest.mark.timeout(60)

IDLE_S = 1.0
# Measured on the 2-core machine: 49-59 % of a core with timeout 0, 4.6 % with 0.001 (idle,
# 5 s). A spinning thread on a loaded machine still gets far more than this bound.
MAX_IDLE_CPU_FRACTION = 0.2


def idle_cpu_fraction(bus_kwargs: dict) -> float:
    network = canopen.Network(can.Bus(**bus_kwargs))
    network.connect()  # canopen's Notifier thread now waits for frames
    try:
        time.sleep(0.1)
        cpu0, wall0 = time.process_time(), time.perf_counter()
        time.sleep(IDLE_S)
        return (time.process_time() - cpu0) / (time.perf_counter() - wall0)
    finally:
        network.disconnect()


def test_an_idle_canopen_client_with_the_printed_arguments_does_not_spin() -> None:
    emulator = Emulator(EmulatorSpec(joints=(EmulatedJointSpec(dxl_id=1, encoder_node_id=5),)))
    try:
        printed = emulator.endpoints()["can"]
        assert printed["interface"] == "slcan" and printed["timeout"] > 0
        fraction = idle_cpu_fraction(printed)
        print(f"\nidle canopen client with the printed slcan arguments: {fraction:.1%} of a core")
        assert fraction < MAX_IDLE_CPU_FRACTION
    finally:
        emulator.close()


@pytest.mark.timing
def test_the_measure_tells_a_spinning_client() -> None:
    """The same measure with timeout 0: the bound above is not one nothing could exceed."""
    reason = timing_is_unreliable(client_spins=True)
    if reason is not None:  # a spinning thread's share of a CPU is whatever the load leaves
        pytest.skip(f"a spinning client's CPU share is not measurable now: {reason}")
    emulator = Emulator(EmulatorSpec(joints=(EmulatedJointSpec(dxl_id=1, encoder_node_id=5),)))
    try:
        spinning = dict(emulator.endpoints()["can"], timeout=0)
        fraction = idle_cpu_fraction(spinning)
        print(f"\nidle canopen client with slcan timeout 0: {fraction:.1%} of a core")
        assert fraction > MAX_IDLE_CPU_FRACTION
    finally:
        emulator.close()
