"""Helpers that serve emulated CAN nodes for tests and demos.

`serve_segment_in_subprocess(...)`: a CAN segment of synthetic nodes behind an `SlcanPty`, in a
SEPARATE PROCESS (multiprocessing "spawn"), so that the test process talks to it through a
real serial port exactly as it would to a USB CAN adapter:

    with serve_segment_in_subprocess([SyntheticEncoder(node_id=5, angle_rad=0.3)]) as served:
        bus = can.Bus(**served.bus_kwargs)   # interface="slcan", channel=<pty>, ...

The child runs in real time (its clock is time.monotonic() since it started), its angles and
forces are fixed or move at a constant rate, and `served.set_fault(...)` injects a node fault.
The context manager always stops the child (stop request, then terminate, then kill).

`serve_in_background(runner, clock)`: a thread that keeps pumping an in-process `NodeRunner`
(on python-can's `virtual` interface), for phases where the host blocks in a library call
(e.g. canopen's SDO client) and nobody else can pump. Lock-step users call `runner.pump` instead.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import select
import threading
import time
import traceback
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from typing import Any

from sim_backend.canbus.encoder_node import LinkEncoderNode
from sim_backend.canbus.force_sensor_node import ForceSensorNode
from sim_backend.canbus.segment import CanNode, CanSegment, NodeRunner
from sim_backend.canbus.slave import DEFAULT_BOOTUP_DELAY_S, SensorFault
from sim_backend.canbus.slcan_pty import SlcanPty

_CHILD_IDLE_WAKEUP_S = 0.05  # the child's longest sleep; the nodes' timers wake it earlier


@dataclass(frozen=True)
class SyntheticEncoder:
    """An encoder node whose link angle is angle_rad + angular_velocity_rad_s * t."""

    node_id: int
    angle_rad: float = 0.0
    angular_velocity_rad_s: float = 0.0
    counts_per_rev: int = 983_040
    direction: int = +1
    heartbeat_ms: int = 100
    tpdo_transmission_type: int = 1
    seed: int = 0
    bootup_delay_s: float = DEFAULT_BOOTUP_DELAY_S


@dataclass(frozen=True)
class SyntheticForceSensor:
    """A force-sensor node whose force is force_n + rate_n_per_s * t."""

    node_id: int
    force_n: float = 0.0
    rate_n_per_s: float = 0.0
    heartbeat_ms: int = 100
    tpdo_transmission_type: int = 1
    seed: int = 0
    bootup_delay_s: float = DEFAULT_BOOTUP_DELAY_S


@dataclass
class ServedSegment:
    """Handle on a segment served in a child process."""

    port_path: str
    bus_bitrate: int
    bus_kwargs: dict[str, Any] = field(default_factory=dict)
    _control: Connection | None = None

    def set_fault(self, node_id: int, mode: str, noise_counts_rms: float = 0.0) -> None:
        """Set the fault of one node in the child; returns once the child applied it."""
        if self._control is None:
            raise RuntimeError("the served segment has been stopped")
        SensorFault(mode, noise_counts_rms).check()  # refuse a typo here, not in the child
        self._control.send(("fault", node_id, mode, noise_counts_rms))
        _expect_reply(self._control, "fault", timeout_s=5.0)


def build_node(
    spec: SyntheticEncoder | SyntheticForceSensor, clock: Callable[[], float]
) -> CanNode:
    """The emulated node for one synthetic spec, driven by `clock` (s)."""
    if isinstance(spec, SyntheticEncoder):
        return LinkEncoderNode(
            spec.node_id,
            lambda: spec.angle_rad + spec.angular_velocity_rad_s * clock(),
            counts_per_rev=spec.counts_per_rev,
            direction=spec.direction,
            heartbeat_ms=spec.heartbeat_ms,
            seed=spec.seed,
            tpdo_transmission_type=spec.tpdo_transmission_type,
            bootup_delay_s=spec.bootup_delay_s,
        )
    return ForceSensorNode(
        spec.node_id,
        lambda: spec.force_n + spec.rate_n_per_s * clock(),
        heartbeat_ms=spec.heartbeat_ms,
        seed=spec.seed,
        tpdo_transmission_type=spec.tpdo_transmission_type,
        bootup_delay_s=spec.bootup_delay_s,
    )


@contextlib.contextmanager
def serve_segment_in_subprocess(
    nodes: Sequence[SyntheticEncoder | SyntheticForceSensor],
    *,
    bus_bitrate: int = 1_000_000,
    start_timeout_s: float = 20.0,
) -> Iterator[ServedSegment]:
    """Serve synthetic nodes behind an SlcanPty in a spawned child process (see module doc)."""
    context = multiprocessing.get_context("spawn")
    parent_end, child_end = context.Pipe()
    process = context.Process(
        target=_serve_child,
        args=(child_end, tuple(nodes), bus_bitrate),
        name="can-segment-emulator",
        daemon=True,
    )
    process.start()
    child_end.close()
    try:
        port_path = _expect_reply(parent_end, "ready", timeout_s=start_timeout_s)[1]
        served = ServedSegment(
            port_path=port_path,
            bus_bitrate=bus_bitrate,
            bus_kwargs={
                "interface": "slcan",
                "channel": port_path,
                "bitrate": bus_bitrate,
                "sleep_after_open": 0,
            },
            _control=parent_end,
        )
        yield served
        served._control = None
    finally:
        with contextlib.suppress(OSError, BrokenPipeError):
            parent_end.send(("stop",))
        process.join(timeout=3.0)
        if process.is_alive():
            process.terminate()
            process.join(timeout=2.0)
        if process.is_alive():
            process.kill()
            process.join(timeout=2.0)
        parent_end.close()


def _expect_reply(connection: Connection, kind: str, *, timeout_s: float) -> tuple[Any, ...]:
    if not connection.poll(timeout_s):
        raise TimeoutError(f"CAN segment emulator process: no {kind!r} reply in {timeout_s} s")
    reply = connection.recv()
    if reply[0] == "error":
        raise RuntimeError(f"CAN segment emulator process failed:\n{reply[1]}")
    if reply[0] != kind:
        raise RuntimeError(f"CAN segment emulator process: expected {kind!r}, got {reply!r}")
    return reply


def _serve_child(
    control: Connection,
    specs: tuple[SyntheticEncoder | SyntheticForceSensor, ...],
    bus_bitrate: int,
) -> None:
    try:
        start = time.monotonic()

        def clock() -> float:
            return time.monotonic() - start

        nodes = {spec.node_id: build_node(spec, clock) for spec in specs}
        segment = CanSegment(nodes.values(), bitrate=bus_bitrate)
        with SlcanPty(bus_bitrate=bus_bitrate) as adapter:
            # The nodes were powered before anyone connected: their power-on boot-up goes out
            # now, to a closed channel (sent later, it could pass for the answer to a host's
            # first NMT reset while the node, in fact, is restarting).
            for frame in segment.poll(clock()):
                adapter.send_frame(frame)
            control.send(("ready", adapter.port_path))
            while True:
                wait_s = _CHILD_IDLE_WAKEUP_S
                due_s = segment.next_due_s()
                if due_s is not None:
                    wait_s = min(wait_s, max(0.0, due_s - clock()))
                readable, _, _ = select.select([adapter.fileno(), control], [], [], wait_s)
                if control in readable:
                    request = control.recv()
                    if request[0] == "stop":
                        return
                    if request[0] == "fault":
                        _, node_id, mode, noise = request
                        nodes[node_id].fault.mode = mode
                        nodes[node_id].fault.noise_counts_rms = noise
                        nodes[node_id].fault.check()
                        control.send(("fault",))
                now_s = clock()
                for frame in adapter.read_frames():
                    for reply in segment.deliver(frame, now_s):
                        adapter.send_frame(reply)
                for frame in segment.poll(now_s):
                    adapter.send_frame(frame)
    except Exception:  # noqa: BLE001 - reported to the parent instead of dying silently
        with contextlib.suppress(OSError, BrokenPipeError):
            control.send(("error", traceback.format_exc()))


@contextlib.contextmanager
def serve_in_background(
    runner: NodeRunner,
    clock: Callable[[], float] = time.monotonic,
    *,
    wait_s: float = 0.001,
) -> Iterator[NodeRunner]:
    """Pump `runner` from a thread while the block runs (in-process, not lock-step)."""
    stop = threading.Event()
    failure: list[BaseException] = []

    def serve() -> None:
        try:
            while not stop.is_set():
                runner.pump_blocking(clock, wait_s)
        except BaseException as error:  # noqa: BLE001 - surfaced in the caller's thread below
            failure.append(error)

    thread = threading.Thread(target=serve, name="can-node-runner", daemon=True)
    thread.start()
    try:
        yield runner
    finally:
        stop.set()
        thread.join(timeout=5.0)
    if failure:
        raise RuntimeError("the background CAN node runner failed") from failure[0]
