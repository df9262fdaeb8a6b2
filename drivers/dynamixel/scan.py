"""Find the Dynamixel devices that answer on a port (what `hil scan` shows).

First one broadcast PING (Protocol 2.0: every device answers, in ID order; one SDK call, which
waits its own fixed ~0.8 s timeout). A reply that collided or was corrupted is lost from it, so
then PING one by one, bounded by the short per-call timeout of `LowLatencyPortHandler`: the IDs
asked for that the broadcast missed, or every ID 0..252 if the broadcast found nothing.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass

from dynamixel_sdk import COMM_SUCCESS, PacketHandler

from drivers.dynamixel.config import MAX_DXL_ID
from drivers.dynamixel.control_table import model_name
from drivers.dynamixel.port import open_port

FIRMWARE_VERSION_ADDRESS = 6  # Protocol 2.0 devices: Firmware Version (1 byte) at 6


@dataclass(frozen=True)
class FoundDevice:
    """A device that answered PING. firmware_version is None if it could not be read."""

    dxl_id: int
    model_number: int
    model_name: str
    firmware_version: int | None


def scan(
    port: str,
    baudrate: int,
    ids: Iterable[int] | None = None,
    *,
    latency_timer_ms: float = 1.0,
    on_ping: Callable[[int, int], None] | None = None,
) -> list[FoundDevice]:
    """Devices answering on `port` at `baudrate`, sorted by ID.

    ids: restricts the result; those the broadcast missed are pinged one by one. Without ids,
    every ID 0..252 is pinged one by one only if the broadcast found nothing (about 1 s more
    with the default timeout). Raises `BusError` with a clear message if the port cannot be
    opened or the SDK cannot set the baud rate. Read-only: sends only PING and READ.
    on_ping(done, of): called after each single PING of the fallback (for a progress bar).
    """
    explicit_ids = ids is not None
    wanted = sorted(set(range(MAX_DXL_ID + 1) if ids is None else ids))
    bad = [dxl_id for dxl_id in wanted if not 0 <= dxl_id <= MAX_DXL_ID]
    if bad:
        raise ValueError(f"Dynamixel IDs must be in 0..{MAX_DXL_ID}, got {bad}")
    handler = open_port(port, baudrate, latency_timer_ms=latency_timer_ms)
    packet = PacketHandler(2.0)
    try:
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
            for done, dxl_id in enumerate(wanted, start=1):
                if dxl_id in found:
                    continue
                model, result, _ = packet.ping(handler, dxl_id)
                if on_ping is not None:
                    on_ping(done, len(wanted))
                if result != COMM_SUCCESS:
                    continue
                firmware, result, _ = packet.read1ByteTxRx(
                    handler, dxl_id, FIRMWARE_VERSION_ADDRESS
                )
                found[dxl_id] = (model, firmware if result == COMM_SUCCESS else None)
    finally:
        handler.closePort()
    return [
        FoundDevice(dxl_id, model, model_name(model), firmware)
        for dxl_id, (model, firmware) in sorted(found.items())
    ]
