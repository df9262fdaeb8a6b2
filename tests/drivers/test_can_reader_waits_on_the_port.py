"""The link-encoder reader waits for its frames in select() on the serial port, so its tick
neither costs the slcan `timeout` keyword (python-can's serial read timeout, paid by every
empty recv()) nor spins a core when that timeout is 0."""

from __future__ import annotations

import statistics
import time

import can
import pytest

from drivers.canbus import LinkEncoderConfig, LinkEncoderReader
from sim_backend.canbus.testing import SyntheticEncoder, serve_segment_in_subprocess

pytestmark = pytest.mark.timeout(60)

LONG_SERIAL_TIMEOUT_S = 0.05


@pytest.mark.timing
def test_a_tick_does_not_cost_the_serial_read_timeout() -> None:
    """Reading with recv(timeout) paid 0.05 s per tick here (the empty read that ends the
    drain before each SYNC); waiting in select() pays only the round trip (~1 ms)."""
    with serve_segment_in_subprocess([SyntheticEncoder(5, angle_rad=0.3)]) as served:
        bus = can.Bus(**served.bus_kwargs, timeout=LONG_SERIAL_TIMEOUT_S)
        reader = LinkEncoderReader(bus, [LinkEncoderConfig(5)])
        try:
            reader.open()
            ticks_s = []
            for _ in range(40):
                started = time.perf_counter()
                reading = reader.read(timeout_s=0.5)
                ticks_s.append(time.perf_counter() - started)
                assert reading.all_valid
        finally:
            reader.close()
    median_s = statistics.median(ticks_s)
    print(
        f"\nSYNC -> TPDO with slcan timeout {LONG_SERIAL_TIMEOUT_S} s: "
        f"median {median_s * 1e3:.2f} ms"
    )
    assert median_s < LONG_SERIAL_TIMEOUT_S / 2


def test_waiting_for_a_dead_node_does_not_spin_even_with_timeout_zero() -> None:
    with serve_segment_in_subprocess([SyntheticEncoder(5), SyntheticEncoder(6)]) as served:
        bus = can.Bus(**served.bus_kwargs, timeout=0)  # python-can would busy-poll
        reader = LinkEncoderReader(bus, [LinkEncoderConfig(5), LinkEncoderConfig(6)])
        try:
            reader.open()
            served.set_fault(6, "dead")
            cpu0, wall0 = time.process_time(), time.perf_counter()
            for _ in range(5):
                reading = reader.read(timeout_s=0.1)  # waits the full 0.1 s for node 6
                assert reading.valid.tolist() == [True, False]
            wall_s = time.perf_counter() - wall0
            fraction = (time.process_time() - cpu0) / wall_s
        finally:
            reader.close()
    print(f"\nwaiting 0.1 s x 5 for a dead node: {fraction:.1%} of a core")
    assert wall_s >= 0.5
    assert fraction < 0.2  # a spinning wait uses most of a core
