"""One CAN bus segment of emulated nodes, and a runner that serves it on a python-can bus.

`CanSegment` is the wire between the nodes: every node sees every frame except its own (like a
real bus, where a transmitter does not receive its own frame), and the replies of one round
go out in CAN arbitration order (lowest identifier first). It is pure: frames in, frames out,
time from the caller.

`NodeRunner` connects a segment to a python-can bus (in-process: the `virtual` interface):
`pump(now_s)` takes every frame waiting on the bus, delivers it, and sends the replies and the
nodes' own time-driven frames. Called once per emulator step it is deterministic and needs no
thread; `pump_blocking` is for a serving loop that must wait for the host.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterable
from typing import Protocol

import can

# Bound on reply chains within one delivery (nodes that answer each other forever are a bug).
_MAX_FRAMES_PER_DELIVERY = 10_000


class CanNode(Protocol):
    """What a segment needs of a node: the pure handler API of the emulated nodes."""

    node_id: int

    def handle(self, msg: can.Message, now_s: float) -> list[can.Message]: ...

    def poll(self, now_s: float) -> list[can.Message]: ...

    def next_due_s(self) -> float | None: ...


class CanSegment:
    """One CAN bus segment: its nodes and its bitrate (bit/s, for adapters to check)."""

    def __init__(self, nodes: Iterable[CanNode], *, bitrate: int = 1_000_000) -> None:
        self.nodes: tuple[CanNode, ...] = tuple(nodes)
        node_ids = [node.node_id for node in self.nodes]
        duplicates = sorted({node_id for node_id in node_ids if node_ids.count(node_id) > 1})
        if duplicates:
            raise ValueError(f"two nodes on one CAN segment share node ID(s) {duplicates}")
        if bitrate <= 0:
            raise ValueError(f"bitrate must be a positive number of bit/s, got {bitrate}")
        self.bitrate = bitrate
        self._listening: dict[int, tuple[CanNode, ...]] = {}
        self._next_due: tuple[float | None] | None = None  # cached: nodes change when called

    def deliver(self, msg: can.Message, now_s: float) -> list[can.Message]:
        """Frames the nodes put on the bus in reaction to `msg` from outside the segment."""
        self._next_due = None
        return self._propagate([(msg, None)], now_s, from_outside=True)

    def next_due_s(self) -> float | None:
        """When the next node sends on its own (boot-up, heartbeat, event timer), or None: an
        event loop waits until then at most, so that these frames go out on time. (A node's
        timers move only when it is handed a frame or polled, through this segment: the
        answer is kept until then.)"""
        if self._next_due is None:
            due = [t for t in (node.next_due_s() for node in self.nodes) if t is not None]
            self._next_due = (min(due) if due else None,)
        return self._next_due[0]

    def poll(self, now_s: float, *, due_only: bool = False) -> list[can.Message]:
        """Frames the nodes send on their own by `now_s`, and any reactions to them.

        due_only: poll only the nodes whose `next_due_s` has come (the others would send
        nothing; a caller that changed a node's fault since polls them all)."""
        nodes = self.nodes
        if due_only:
            nodes = tuple(n for n in nodes if (due := n.next_due_s()) is not None and due <= now_s)
        self._next_due = None
        polled = [(frame, node) for node in nodes for frame in node.poll(now_s)]
        polled.sort(key=_arbitration_key)
        return self._propagate(polled, now_s, from_outside=False)

    def _propagate(
        self,
        initial: list[tuple[can.Message, CanNode | None]],
        now_s: float,
        *,
        from_outside: bool,
    ) -> list[can.Message]:
        on_bus = [] if from_outside else [frame for frame, _ in initial]
        pending = deque(initial)
        # a frame from outside reaches every node (each catches up to now_s); the nodes' own
        # frames (a poll's) were sent by nodes that ran at now_s: like replies, they go only
        # to the nodes they concern, and to any other that was not polled nothing happens
        # but what its next call at a later time does anyway
        first_frames = len(initial) if from_outside else 0
        unpowered: list[CanNode] | None = None
        while pending:
            frame, sender = pending.popleft()
            if first_frames:  # reaches every node: each catches up to now_s
                first_frames -= 1
                hearing = self.nodes
            else:
                # the replies (e.g. a SYNC's TPDOs) go only to the nodes they can concern:
                # every node has run at now_s already, so to any other node such a frame
                # changes nothing but its count of frames unheard while it has no power
                if unpowered is None:
                    unpowered = [n for n in self.nodes if getattr(n, "powered", True) is False]
                hearing = self._listeners_of(frame.arbitration_id)
                if unpowered:
                    hearing = tuple(n for n in self.nodes if n in hearing or n in unpowered)
                elif not hearing:
                    continue  # nobody reacts to it (a TPDO): nothing to ask
            replies = [
                (reply, node)
                for node in hearing
                if node is not sender
                for reply in node.handle(frame, now_s)
            ]
            if not replies:
                continue
            replies.sort(key=_arbitration_key)
            on_bus.extend(reply for reply, _ in replies)
            pending.extend(replies)
            if len(on_bus) > _MAX_FRAMES_PER_DELIVERY:
                raise RuntimeError(
                    f"CAN segment: more than {_MAX_FRAMES_PER_DELIVERY} frames in reply to one "
                    f"frame (0x{frame.arbitration_id:03X}); nodes keep answering each other"
                )
        return on_bus

    def _listeners_of(self, cob_id: int) -> tuple[CanNode, ...]:
        """The nodes that react to frames with this COB-ID (a node that does not say which it
        reacts to, `reacting_cob_ids`, hears everything)."""
        cached = self._listening.get(cob_id)
        if cached is None:
            cached = tuple(
                node
                for node in self.nodes
                if getattr(node, "reacting_cob_ids", None) is None
                or cob_id in node.reacting_cob_ids  # type: ignore[attr-defined]
            )
            self._listening[cob_id] = cached
        return cached


def _arbitration_key(item: tuple[can.Message, object]) -> int:
    return item[0].arbitration_id


class NodeRunner:
    """Serves a CanSegment on a python-can bus (the nodes' side of the bus)."""

    def __init__(self, bus: can.BusABC, segment: CanSegment) -> None:
        self.bus = bus
        self.segment = segment

    def pump(self, now_s: float) -> int:
        """Handle every frame waiting on the bus, then the nodes' timers; returns frames read."""
        return self._pump(None, now_s)

    def pump_blocking(self, clock: Callable[[], float], timeout_s: float) -> int:
        """Wait up to `timeout_s` for a frame, then pump at `clock()`; returns frames read."""
        first = self.bus.recv(timeout=timeout_s)
        return self._pump(first, clock())

    def _pump(self, first: can.Message | None, now_s: float) -> int:
        handled = 0
        msg = first if first is not None else self.bus.recv(timeout=0.0)
        while msg is not None:
            for reply in self.segment.deliver(msg, now_s):
                self.bus.send(reply)
            handled += 1
            msg = self.bus.recv(timeout=0.0)
        for frame in self.segment.poll(now_s):
            self.bus.send(frame)
        return handled
