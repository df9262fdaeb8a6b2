"""`LowLatencyPortHandler` sleeps while the SDK waits for a reply: the SDK's rxPacket loop calls
readPort without pause, so a spinning read is thousands of calls per millisecond; ours is a
handful per wait, and the reply still comes back whole and on time."""

from __future__ import annotations

import os
import threading
import time

import pytest
from dynamixel_sdk import COMM_RX_TIMEOUT, COMM_SUCCESS, PacketHandler

from drivers.dynamixel.port import LowLatencyPortHandler

# Both tests assert wall-clock figures (a reply 1.5 ms into an 11 ms wait): beside another
# pytest worker the replier thread can miss the wait, so they run with the timing tests alone.
pytestmark = pytest.mark.timing

# The status packet of the e-Manual's Protocol 2.0 PING example (ID 1, model 1030, firmware 38).
PING_STATUS_ID1 = bytes.fromhex("FFFFFD000107005500060426655D")


class CountingPort(LowLatencyPortHandler):
    reads = 0

    def readPort(self, length: int) -> bytes:
        self.reads += 1
        return super().readPort(length)


@pytest.fixture
def pty_port():
    controller, device = os.openpty()
    port = CountingPort(os.ttyname(device), latency_timer_ms=1.0, timeout_margin_ms=2.0)
    assert port.setBaudRate(4_000_000)
    yield port, controller
    port.closePort()
    os.close(controller)
    os.close(device)


def test_a_silent_device_costs_its_timeout_in_a_few_reads(pty_port) -> None:
    port, _ = pty_port
    packet = PacketHandler(2.0)
    port.setPacketTimeout(11)  # what the SDK sets for a PING's reply
    timeout_s = port.packet_timeout / 1000.0
    started = time.perf_counter()
    _, result = packet.rxPacket(port, False)
    waited = time.perf_counter() - started
    assert result == COMM_RX_TIMEOUT
    assert waited >= timeout_s * 0.99
    assert port.reads < 10  # spinning: tens of thousands in 4 ms


def test_a_reply_that_arrives_mid_wait_is_read_at_once_and_whole(pty_port) -> None:
    port, controller = pty_port
    packet = PacketHandler(2.0)
    port.setPacketTimeout(11)
    sent_at: list[float] = []

    def answer() -> None:
        time.sleep(0.0015)
        sent_at.append(time.perf_counter())
        os.write(controller, PING_STATUS_ID1)

    replier = threading.Thread(target=answer)
    replier.start()
    rx, result = packet.rxPacket(port, False)
    received_at = time.perf_counter()
    replier.join()
    assert result == COMM_SUCCESS, packet.getTxRxResult(result)
    assert bytes(rx) == PING_STATUS_ID1
    assert received_at - sent_at[0] < port.packet_timeout / 1000.0  # woken by the bytes
    assert port.reads < 10
