"""`scan` reports its progress and `scan_bauds` (the `hil scan` loop) keeps to a time budget.

Against the emulated chain in another process (unmodified dynamixel-sdk). A silent port is the
emulated line with every device silent: it reads and discards what the host sends, so the
host's writes never block, and nothing answers.
"""

from __future__ import annotations

import time

import pytest

from drivers.dynamixel import ScanProgress, ScanStep, scan, scan_bauds
from sim_backend.dynamixel.testing import spawn_emulated_chain

pytestmark = pytest.mark.timeout(120)

BAUD_4M, BAUD_1M, BAUD_57K = 4_000_000, 1_000_000, 57_600
# The rates `hil scan` tries, in its order (hil/commands.py SCAN_BAUDRATES).
HIL_SCAN_BAUDRATES = (3_000_000, 4_000_000, 1_000_000, 2_000_000, 57_600, 115_200, 9_600)


def test_scan_of_a_silent_port_reports_every_step() -> None:
    events: list[ScanProgress] = []
    with spawn_emulated_chain(ids=(1,)) as emu:
        emu.faults(silent_ids={1})
        assert scan(emu.port_path, BAUD_4M, progress=events.append) == []
    steps = [event.step for event in events]
    assert steps[:2] == [ScanStep.BAUDRATE, ScanStep.BROADCAST]
    pings = events[2:]
    assert [event.step for event in pings] == [ScanStep.PING] * 253
    assert [event.dxl_id for event in pings] == list(range(253))
    assert [event.pings_done for event in pings] == list(range(253))
    assert {event.pings_planned for event in pings} == {253}
    assert all(event.baudrate == BAUD_4M and event.found == 0 for event in events)
    elapsed = [event.elapsed_s for event in events]
    assert elapsed == sorted(elapsed) and elapsed[-1] > elapsed[2]


def test_scan_bauds_stops_at_the_rate_that_answers() -> None:
    events: list[ScanProgress] = []
    with spawn_emulated_chain(ids=(3, 9), baud_index=3, enforce_baud=True) as emu:
        report = scan_bauds(emu.port_path, (BAUD_4M, BAUD_1M, BAUD_57K), progress=events.append)
    assert [device.dxl_id for device in report.devices] == [3, 9]
    assert report.baudrate == BAUD_1M and report.bauds_tried == (BAUD_4M, BAUD_1M)
    assert report.complete
    started = [event.baudrate for event in events if event.step is ScanStep.BAUDRATE]
    assert started == [BAUD_4M, BAUD_1M]


@pytest.mark.timing
def test_scan_bauds_keeps_to_its_time_budget_and_says_it_stopped() -> None:
    budget_s = 1.2
    with spawn_emulated_chain(ids=(1,)) as emu:
        emu.faults(silent_ids={1})
        started = time.monotonic()
        report = scan_bauds(emu.port_path, (BAUD_4M, BAUD_1M, BAUD_57K), time_budget_s=budget_s)
        elapsed_s = time.monotonic() - started
    print(f"\nsilent port, budget {budget_s} s: stopped after {elapsed_s:.2f} s, {report}")
    assert not report.complete and report.devices == ()
    assert report.bauds_tried[0] == BAUD_4M and BAUD_57K not in report.bauds_tried
    # it may overrun by one SDK call: the broadcast's fixed timeout (0.8 s at 1 Mbps)
    assert budget_s <= elapsed_s < budget_s + 0.8 + 0.5


def test_scan_bauds_refuses_a_meaningless_budget() -> None:
    with pytest.raises(ValueError, match="time_budget_s"):
        scan_bauds("/dev/null", (BAUD_4M,), time_budget_s=0.0)
    with pytest.raises(ValueError, match="time_budget_s"):
        scan_bauds("/dev/null", (BAUD_4M,), time_budget_s=float("nan"))


@pytest.mark.slow
def test_the_hil_scan_rates_on_a_silent_port_take_this_long() -> None:
    """The figure behind `hil scan`'s silence: every rate, broadcast plus 253 PINGs each."""
    per_rate: dict[int, float] = {}

    def note(event: ScanProgress) -> None:
        if event.step is ScanStep.BAUDRATE:
            per_rate[event.baudrate] = event.elapsed_s

    with spawn_emulated_chain(ids=(1,)) as emu:
        emu.faults(silent_ids={1})
        report = scan_bauds(emu.port_path, HIL_SCAN_BAUDRATES, progress=note)
    assert report.complete and report.devices == ()
    marks = [*per_rate.values(), report.elapsed_s]
    lines = [
        f"  {baud:>9} bps: {end - begin:5.2f} s"
        for baud, begin, end in zip(per_rate, marks, marks[1:], strict=False)
    ]
    print(f"\nsilent port, {len(HIL_SCAN_BAUDRATES)} rates: {report.elapsed_s:.1f} s")
    print("\n".join(lines))
