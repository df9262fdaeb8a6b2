"""Find the Dynamixel devices that answer on a port (what `hil scan` shows).

At one baud rate (`scan`): first one broadcast PING (Protocol 2.0: every device answers, in ID
order; one SDK call, which waits its own fixed timeout, ~0.8 s at 4 Mbps and ~4.4 s at 9600
bps). A reply that collided or was corrupted is lost from it, so then PING one by one, bounded
by the short per-call timeout of `LowLatencyPortHandler`: the IDs asked for that the broadcast
missed, or every ID 0..252 if the broadcast found nothing.

Over several baud rates (`scan_bauds`, the `hil scan` loop): the rates in turn until one has
devices (devices on one line share a rate), with an optional time budget. Measured on a silent
port (the emulated line, every device silent) with the default 1 ms latency
(tests/drivers/test_dxl_scan_progress.py, the slow test): 1.8-1.9 s per rate at 1-4 Mbps
(broadcast ~0.8 s + 253 PINGs of ~4 ms), 2.4 s at 115,200, 2.9 s at 57,600 and 8.4 s at 9,600
bps (the broadcast's timeout grows with the byte time): 21.1 s over the seven rates `hil scan`
tries.

Both report progress through an optional callback, once per rate tried, per broadcast and per
ID pinged, so that a front end can show that a long scan is alive.
"""

from __future__ import annotations

import enum
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

from dynamixel_sdk import COMM_SUCCESS, PacketHandler

from drivers.dynamixel.config import MAX_DXL_ID
from drivers.dynamixel.control_table import model_name
from drivers.dynamixel.port import LowLatencyPortHandler, open_port

FIRMWARE_VERSION_ADDRESS = 6  # Protocol 2.0 devices: Firmware Version (1 byte) at 6


@dataclass(frozen=True)
class FoundDevice:
    """A device that answered PING. firmware_version is None if it could not be read."""

    dxl_id: int
    model_number: int
    model_name: str
    firmware_version: int | None


class ScanStep(enum.Enum):
    """What a scan is about to do (see `ScanProgress`)."""

    BAUDRATE = "baudrate"  # opening the port at a new rate
    BROADCAST = "broadcast"  # one broadcast PING (waits the SDK's fixed timeout)
    PING = "ping"  # one PING of `dxl_id`


@dataclass(frozen=True)
class ScanProgress:
    """One step of a scan, reported before it is taken.

    pings_done / pings_planned: one-by-one PINGs at this rate (planned is 0 until the broadcast
    showed which are needed). found: devices found at this rate so far. elapsed_s: since the
    scan began (`scan_bauds`) or since this rate began (`scan`).
    """

    step: ScanStep
    baudrate: int
    dxl_id: int | None
    pings_done: int
    pings_planned: int
    found: int
    elapsed_s: float


ScanProgressCallback = Callable[[ScanProgress], None]


@dataclass(frozen=True)
class ScanReport:
    """What `scan_bauds` found, and whether it got to try everything it was asked to.

    baudrate: the rate the devices answered at (None if none answered). complete: False if the
    time budget ran out first (then `bauds_tried` says how far it got, and the last of them
    may have been tried only in part).
    """

    port: str
    devices: tuple[FoundDevice, ...]
    baudrate: int | None
    bauds_tried: tuple[int, ...]
    complete: bool
    elapsed_s: float


def scan(
    port: str,
    baudrate: int,
    ids: Iterable[int] | None = None,
    *,
    latency_timer_ms: float = 1.0,
    progress: ScanProgressCallback | None = None,
) -> list[FoundDevice]:
    """Devices answering on `port` at `baudrate`, sorted by ID.

    ids: restricts the result; those the broadcast missed are pinged one by one. Without ids,
    every ID 0..252 is pinged one by one only if the broadcast found nothing (about 1 s more
    with the default timeout). Raises `BusError` with a clear message if the port cannot be
    opened or the SDK cannot set the baud rate. Read-only: sends only PING and READ.
    progress: called before the broadcast and before each one-by-one PING.
    """
    wanted, explicit = _wanted_ids(ids)
    found, _ = _scan_at(
        port, baudrate, wanted, explicit, latency_timer_ms, progress, time.monotonic(), None
    )
    return found


def scan_bauds(
    port: str,
    baudrates: Sequence[int],
    ids: Iterable[int] | None = None,
    *,
    latency_timer_ms: float = 1.0,
    progress: ScanProgressCallback | None = None,
    time_budget_s: float | None = None,
    stop_at_first_found: bool = True,
) -> ScanReport:
    """`scan` at each rate of `baudrates` in turn, until one has devices (`stop_at_first_found`)
    or `time_budget_s` has passed (checked between PINGs: one SDK call may overrun it, by the
    broadcast's timeout at most). Raises `BusError` as `scan` does.
    """
    if time_budget_s is not None and not time_budget_s > 0:
        raise ValueError(f"time_budget_s must be > 0 s (or None), got {time_budget_s!r}")
    if not baudrates:
        raise ValueError("scan_bauds needs at least one baud rate")
    wanted, explicit = _wanted_ids(ids)
    started = time.monotonic()
    deadline = None if time_budget_s is None else started + time_budget_s
    devices: list[FoundDevice] = []
    tried: list[int] = []
    found_at: int | None = None
    complete = True
    for baudrate in baudrates:
        if deadline is not None and time.monotonic() >= deadline:
            complete = False
            break
        tried.append(baudrate)
        found, finished = _scan_at(
            port, baudrate, wanted, explicit, latency_timer_ms, progress, started, deadline
        )
        if found:
            devices.extend(found)
            found_at = baudrate if found_at is None else found_at
        if not finished:
            complete = False
            break
        if found and stop_at_first_found:
            break
    return ScanReport(
        port=port,
        devices=tuple(devices),
        baudrate=found_at,
        bauds_tried=tuple(tried),
        complete=complete,
        elapsed_s=time.monotonic() - started,
    )


def _wanted_ids(ids: Iterable[int] | None) -> tuple[list[int], bool]:
    wanted = sorted(set(range(MAX_DXL_ID + 1) if ids is None else ids))
    bad = [dxl_id for dxl_id in wanted if not 0 <= dxl_id <= MAX_DXL_ID]
    if bad:
        raise ValueError(f"Dynamixel IDs must be in 0..{MAX_DXL_ID}, got {bad}")
    return wanted, ids is not None


def _scan_at(
    port: str,
    baudrate: int,
    wanted: list[int],
    explicit_ids: bool,
    latency_timer_ms: float,
    progress: ScanProgressCallback | None,
    started: float,
    deadline: float | None,
) -> tuple[list[FoundDevice], bool]:
    """(devices found, finished) at one rate; finished is False if the deadline cut it short."""

    def report(step: ScanStep, dxl_id: int | None, done: int, planned: int, found: int) -> None:
        if progress is not None:
            elapsed_s = time.monotonic() - started
            progress(ScanProgress(step, baudrate, dxl_id, done, planned, found, elapsed_s))

    report(ScanStep.BAUDRATE, None, 0, 0, 0)
    handler: LowLatencyPortHandler = open_port(port, baudrate, latency_timer_ms=latency_timer_ms)
    packet = PacketHandler(2.0)
    finished = True
    try:
        report(ScanStep.BROADCAST, None, 0, 0, 0)
        answers, _ = packet.broadcastPing(handler)
        # Replies that passed their CRC are good even if a later one collided or was corrupted.
        found: dict[int, tuple[int, int | None]] = {
            dxl_id: (model, firmware)
            for dxl_id, (model, firmware) in answers.items()
            if dxl_id in wanted
        }
        # Fall back to one PING per ID: for the IDs asked for that the broadcast missed, or for
        # the whole range if the broadcast found nothing at all.
        if explicit_ids or not found:
            missing = [dxl_id for dxl_id in wanted if dxl_id not in found]
            for done, dxl_id in enumerate(missing):
                if deadline is not None and time.monotonic() >= deadline:
                    finished = False
                    break
                report(ScanStep.PING, dxl_id, done, len(missing), len(found))
                model, result, _ = packet.ping(handler, dxl_id)
                if result != COMM_SUCCESS:
                    continue
                firmware, result, _ = packet.read1ByteTxRx(
                    handler, dxl_id, FIRMWARE_VERSION_ADDRESS
                )
                found[dxl_id] = (model, firmware if result == COMM_SUCCESS else None)
    finally:
        handler.closePort()
    devices = [
        FoundDevice(dxl_id, model, model_name(model), firmware)
        for dxl_id, (model, firmware) in sorted(found.items())
    ]
    return devices, finished
