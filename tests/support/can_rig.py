"""Emulated CAN nodes and the link-encoder reader on one python-can virtual channel, sharing a
simulated clock: `open()` serves the nodes from a background thread while canopen's SDO client
blocks (the clock runs in real time then, so a node booting after an NMT reset gets there); the
ticks afterwards are lock-step: send_sync() -> the nodes are pumped -> collect()."""

from __future__ import annotations

import math
import time
import uuid

import can

from drivers.canbus import LinkEncoderConfig, LinkEncoderReader, LinkReading
from sim_backend.canbus import CanSegment, NodeRunner
from sim_backend.canbus.testing import serve_in_background

TICK_S = 0.005


class Rig:
    """Nodes and a reader on one virtual channel, sharing a simulated clock."""

    def __init__(self, nodes: list, encoders: list[LinkEncoderConfig], **reader_kwargs) -> None:
        channel = f"test-can-driver-{uuid.uuid4()}"
        self.now_s = 0.0
        self.nodes = nodes
        self.node_bus = can.Bus(interface="virtual", channel=channel)
        self.runner = NodeRunner(self.node_bus, CanSegment(nodes))
        # The nodes were powered before the reader came: their power-on boot-up is history
        # (had it arrived after the reader's NMT reset, it would pass for the reset's answer).
        self.runner.pump(self.now_s)
        self.reader = LinkEncoderReader(
            can.Bus(interface="virtual", channel=channel),
            encoders,
            clock=lambda: self.now_s,
            bus_description=f"virtual {channel}",
            **reader_kwargs,
        )
        self.channel = channel
        self.description = f"virtual {channel}"

    def serve_while(self, action) -> None:
        """Serve the nodes while `action` blocks (canopen's SDO client); the shared clock runs
        in real time meanwhile, so that a node booting after an NMT reset gets there."""
        base_s, started = self.now_s, time.monotonic()

        def running_clock() -> float:
            self.now_s = max(self.now_s, base_s + time.monotonic() - started)
            return self.now_s

        with serve_in_background(self.runner, running_clock):
            action()
        # Lock-step ticks resume on a fixed grid whatever the real time the action took, so
        # that sessions stay deterministic: the next multiple of 10 s.
        self.now_s = 10.0 * (math.floor(base_s / 10.0) + 1)
        assert self.now_s > base_s + time.monotonic() - started, "serving took over 10 s"
        self.runner.pump(self.now_s)  # the heartbeats overdue after the jump go out now

    def open(self) -> None:
        self.serve_while(self.reader.open)

    def tick(self, timeout_s: float = 0.004) -> LinkReading:
        self.now_s += TICK_S
        self.reader.send_sync()
        self.runner.pump(self.now_s)
        return self.reader.collect(timeout_s)

    def close(self) -> None:
        self.reader.close()
        self.node_bus.shutdown()
