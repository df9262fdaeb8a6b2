"""The receive path of the CAN sensor reader, without a thread: wait for frames, route each one.

Waiting: where the bus offers a file descriptor (python-can's `fileno()`: slcan's serial port,
socketcan's socket), the reader sleeps in `select()` until bytes arrive and then takes the
frames with `recv(timeout=0)`, as python-can's own asyncio Notifier does. So it neither spins
nor depends on the slcan `timeout` keyword, which is the serial port's read timeout: python-can's
slcan `recv()` blocks that long in every empty read (1 ms by default: a whole tick's worth of
empty polls in lock-step) and spins a core when it is 0. Buses without a descriptor (`virtual`)
are read with `recv(timeout)`. `collect()` returns within `timeout_s` plus the scheduler's
latency. In-process lock-step: send_sync(), then pump the emulated nodes, then collect().

A TPDO goes to its node's answer for this SYNC (a link encoder's INTEGER32, a force/torque
sensor's two INTEGER16 triples); heartbeats, EMCY and SDO frames go to canopen's handlers, whose
callbacks keep each node's NMT state and the reader's events.
"""

from __future__ import annotations

import select
import struct
import time

import can
import canopen

from drivers.canbus.read_ahead import ReadAheadSerial
from drivers.canbus.sensor_nodes import (
    HEARTBEAT_BOOTUP,
    HEARTBEAT_PRE_OPERATIONAL,
    UNKNOWN_STATE,
    state_name,
)

_INT32 = struct.Struct("<i")
_INT16x3 = struct.Struct("<hhh")
# CiA 301 frame lengths canopen's handlers rely on, by function code (COB-ID & 0x780), for
# the COB-IDs a RemoteNode subscribes to: NMT 0x000, EMCY 0x080+id, SDO 0x580+id, 0x700+id.
_FUNCTION_CODE_MASK = 0x780
_MIN_FRAME_BYTES = {
    0x000: 2,  # NMT command: command specifier, node ID
    0x080: 8,  # EMCY: error code, error register, 5 bytes manufacturer data
    0x580: 8,  # SDO response
    0x700: 1,  # heartbeat / boot-up: the state byte
}
MAX_FRAMES_PER_DRAIN = 1024


class FrameReceiver:
    """The frames of `LinkEncoderReader`'s bus, taken and routed on the caller's thread (a mixin:
    it works on the reader's per-device answer arrays)."""

    def _receive(self, deadline: float) -> can.Message | None:
        """The next frame, waiting until `deadline` (time.monotonic) at most; None if none came.

        With a file descriptor: sleep in select() until bytes arrive, then recv(timeout=0),
        which then returns without waiting; bytes that were no frame (slcan's acknowledgement
        of our own transmission, half a line) send it back to sleep.
        """
        fd = self._fd
        if fd is None:
            return self._bus.recv(timeout=max(deadline - time.monotonic(), 0.0))
        ahead = self._read_ahead
        for _ in range(MAX_FRAMES_PER_DRAIN):
            # bytes a read-ahead port already holds do not make the descriptor readable
            if ahead is None or not ahead.in_waiting:
                wait_s = max(deadline - time.monotonic(), 0.0)
                if not select.select((fd,), (), (), wait_s)[0]:
                    return None
            msg = self._bus.recv(timeout=0.0)
            if msg is not None:
                return msg
        return None  # a babbling port: give the tick back

    def _drain(self) -> None:
        """Handle the frames already received (bounded, so a flooded bus cannot hang a tick)."""
        for _ in range(MAX_FRAMES_PER_DRAIN):
            msg = self._receive(deadline=0.0)  # only what is there now
            if msg is None:
                return
            self._dispatch(msg)

    def _dispatch(self, msg: can.Message) -> None:
        if msg.is_extended_id or msg.is_remote_frame or msg.is_error_frame:
            return
        index = self._tpdo_device.get(msg.arbitration_id)
        if index is None:  # NMT heartbeat, EMCY, SDO: canopen's handlers (callbacks below)
            self._notify_canopen(msg)
            return
        if index >= self._ft_first:  # the force/torque sensors are the last devices
            self._dispatch_wrench(index, self._tpdo_part[msg.arbitration_id], msg)
            return
        data = msg.data
        if len(data) < 4:
            self._events.append(
                f"{self._devices[index].label}: TPDO with {len(data)} bytes ignored (expected 4)"
            )
            return
        if not self._sync_outstanding:
            self._events.append(
                f"{self._devices[index].label}: late TPDO discarded (answered an earlier SYNC)"
            )
            return
        if not self._answered[index]:
            self._answered[index] = True
            self._n_answered += 1
        self._answer_raw[index] = _INT32.unpack_from(data)[0]

    def _dispatch_wrench(self, index: int, part: int, msg: can.Message) -> None:
        """One of a force/torque sensor's two TPDOs: three INTEGER16 channels."""
        device = self._devices[index]
        if len(msg.data) < _INT16x3.size:
            self._events.append(
                f"{device.label}: TPDO with {len(msg.data)} bytes ignored (expected 6)"
            )
            return
        if not self._sync_outstanding:
            self._events.append(f"{device.label}: late TPDO discarded (answered an earlier SYNC)")
            return
        sensor = index - self._ft_first
        self._ft_answer_raw[sensor, 3 * part : 3 * part + 3] = _INT16x3.unpack_from(msg.data)
        self._ft_parts[index] |= 1 << part
        if self._ft_parts[index] == 0b11 and not self._answered[index]:
            self._answered[index] = True
            self._n_answered += 1

    def _notify_canopen(self, msg: can.Message) -> None:
        """Hand a frame to canopen's handlers, unless it is too short for them.

        canopen unpacks these frames with `struct` and raises on a short one (an empty
        heartbeat, a 2-byte EMCY): on the tick path that would end the run, so a frame shorter
        than CiA 301 defines is logged as an event and dropped here.
        """
        cob_id = msg.arbitration_id
        if cob_id not in self._network.subscribers:
            return  # nobody listens (another node's frames, SYNC, PDOs we do not use)
        needed = _MIN_FRAME_BYTES.get(cob_id & _FUNCTION_CODE_MASK)
        if needed is not None and len(msg.data) < needed:
            self._events.append(
                f"malformed frame 0x{cob_id:03X} with {len(msg.data)} byte(s) ignored "
                f"(CiA 301 defines {needed})"
            )
            return
        try:
            self._network.notify(cob_id, msg.data, msg.timestamp)
        except (struct.error, ValueError, KeyError, IndexError) as error:
            self._events.append(f"frame 0x{cob_id:03X} [{bytes(msg.data).hex()}] ignored: {error}")

    def _on_heartbeat(self, index: int, state: int) -> None:
        """canopen heartbeat callback (Notifier thread during open, else collect's thread)."""
        device = self._devices[index]
        with self._heartbeat_seen:
            self._states_since_mark[index].append(state)
            self._heartbeat_seen.notify_all()
        previous = int(self._nmt_state[index])
        booted = state == HEARTBEAT_BOOTUP
        if booted:
            state = HEARTBEAT_PRE_OPERATIONAL  # a booted node is Pre-operational
        if index in self._configuring:
            pass  # the boot-up and state changes that open()/recover_node() caused
        elif booted:
            self._events.append(
                f"{device.label}: boot-up frame (the node restarted; it is Pre-operational "
                "and has its default configuration: call recover_node)"
            )
        elif state != previous and previous != UNKNOWN_STATE:
            self._events.append(
                f"{device.label}: NMT state {state_name(previous)} -> {state_name(state)}"
            )
        if state != previous:
            self._nmt_state[index] = state
            self._state_names = None
        self._last_heartbeat_time[index] = self._clock()

    def _on_emcy(self, index: int, emcy: canopen.emcy.EmcyError) -> None:
        self._events.append(
            f"{self._devices[index].label}: EMCY code 0x{emcy.code:04X}, "
            f"error register 0x{emcy.register:02X}"
        )


def selectable_fileno(bus: can.BusABC) -> int | None:
    """The bus's file descriptor if it has one to select() on (python-can's convention, as its
    Notifier uses it), else None."""
    try:
        fd = bus.fileno()
    except (NotImplementedError, can.CanError, OSError, ValueError):
        return None
    return fd if isinstance(fd, int) and fd >= 0 else None


def read_ahead_port(bus: can.BusABC) -> ReadAheadSerial | None:
    """The read-ahead serial port under python-can's slcan bus, if it has one
    (drivers/canbus/read_ahead.py)."""
    port = getattr(bus, "serialPortOrig", None)
    return port if isinstance(port, ReadAheadSerial) else None
