"""The Protocol 2.0 wire-time model against the protocol's packet sizes, worked by hand."""

from __future__ import annotations

import pytest

from drivers.dynamixel.wire_time import sync_cycle_wire_bytes, sync_cycle_wire_time_s


def test_wire_bytes_follow_the_protocol_packet_sizes() -> None:
    # 6 x H54 reading Present Position .. Present Current (L = 12): SYNC_READ 14 + 6,
    # replies 6 x (11 + 12), SYNC_WRITE 14 + 6 x 5 = 20 + 138 + 44.
    assert sync_cycle_wire_bytes(6, 12) == 202
    # One device, the driver's 15-byte state block: 15 + 26 + 19.
    assert sync_cycle_wire_bytes(1, 15) == 60
    # A 2-byte goal instead of 4 saves 2 bytes per device in the SYNC_WRITE only.
    assert sync_cycle_wire_bytes(6, 12) - sync_cycle_wire_bytes(6, 12, write_bytes=2) == 12


@pytest.mark.parametrize(
    ("baudrate", "return_delay_us", "expected_ms"),
    [
        (57_600, 0, 35.07),  # 2020 bits at the factory baud
        (1_000_000, 0, 2.02),
        (3_000_000, 0, 0.6733),
        (4_000_000, 500, 3.505),  # + 6 x the factory Return Delay Time (500 us)
    ],
)
def test_wire_time_is_ten_bits_per_byte_plus_return_delays(
    baudrate: int, return_delay_us: int, expected_ms: float
) -> None:
    time_s = sync_cycle_wire_time_s(6, 12, baudrate, return_delay_us)
    assert time_s * 1e3 == pytest.approx(expected_ms, rel=1e-3)


def test_wire_time_refuses_meaningless_input() -> None:
    with pytest.raises(ValueError, match="n_devices"):
        sync_cycle_wire_bytes(0, 12)
    with pytest.raises(ValueError, match="baudrate_bps > 0"):
        sync_cycle_wire_time_s(1, 12, 0)
