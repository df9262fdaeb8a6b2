"""Link encoders (CiA 406), an optional force sensor (CiA 404) and optional six-axis force/torque
sensors (CiA 404, six channels in two TPDOs) on CAN, read by SYNC -> TPDO.

Each tick the loop calls `send_sync()` (the SYNC frame 0x080 goes on the bus at once; every
node latches its value now) and then `collect(timeout_s)`, which reads the answering TPDOs
straight from the python-can bus with `bus.recv` up to the deadline and returns as soon as every
node has answered. No background thread decides what `collect()` returns, so a lock-step
experiment is deterministic. Frames that arrive before the SYNC (a TPDO too late for the
previous tick, heartbeats) are taken off the bus by `send_sync()` first, so a reading only
holds answers to THIS SYNC.

`open()` brings each node up with `canopen` (NMT and SDO; a python-can Notifier runs only
during this configuration phase, because canopen's SDO client waits for its answers on a
queue):
  1. NMT reset communication, wait for the boot-up frame 0x700+id [00];
  2. check 0x1000 device type: low 16 bits 0x0196 (CiA 406) for an encoder, 0x0194 (CiA 404)
     for the force sensor; an encoder must report 0x6001 = the configured counts_per_rev;
     the force sensor's unit (0x6131:01) must be newton, 0x6132:01 gives its decimal digits;
  3. check the TPDO mapping (first object 0x60040020 position value, or 0x91300120 AI PV),
     enable the TPDO if its COB-ID is marked invalid, set transmission type 1 (every SYNC);
     a force/torque sensor: 0x6131:00 >= 6 channels, newton (0x21) on channels 1-3 and newton
     metre (0x23, the joule's code: CiA 303-2 has none of its own) on 4-6, 0x6132 their
     resolutions; its force TPDO maps 0x7130:01-03, its torque TPDO 0x7130:04-06 (INTEGER16);
     its answer to a SYNC counts when both TPDOs arrived (`WrenchReading`, N and N m);
  4. set the producer heartbeat time 0x1017, NMT start, and wait for a heartbeat that says
     Operational (0x05).
Every failure names the node, the bus, and what was expected.

Waiting: where the bus offers a file descriptor (python-can's `fileno()`: slcan's serial port,
socketcan's socket), the reader sleeps in `select()` until bytes arrive and then takes the
frames with `recv(timeout=0)`, as python-can's own asyncio Notifier does. So it neither spins
nor depends on the slcan `timeout` keyword, which is the serial port's read timeout: python-can's
slcan `recv()` blocks that long in every empty read (1 ms by default: a whole tick's worth of
empty polls in lock-step) and spins a core when it is 0. Buses without a descriptor (`virtual`)
are read with `recv(timeout)`. `collect()` returns within `timeout_s` plus the scheduler's
latency. In-process lock-step: send_sync(), then pump the emulated nodes, then collect().

Units: counts -> radians in `units.link_angle_rad_from_counts` and PV -> N in
`units.force_n_from_counts`, nowhere else. The TPDO bytes are decoded as a little-endian INTEGER32
(CiA 406 v3.2; an UNSIGNED32 device sends the same bits), so negative link angles are negative.
A multi-turn count that passes the INTEGER32 range wraps (2**31 - 1 + 1 -> -2**31): an encoder's
count is read on through the wrap, each reading the last plus the difference modulo 2**32 (a
link never turns 2**31 counts, 2184 revolutions at 983,040 counts/rev, between two readings);
the first reading after `open()` is taken as it is.
"""

from __future__ import annotations

import contextlib
import functools
import math
import select
import struct
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

import can
import canopen
import numpy as np
from canopen.nmt import NMT_STATES

from drivers.canbus.config import ForceSensorConfig, ForceTorqueSensorConfig, LinkEncoderConfig
from drivers.canbus.object_dictionary import (
    TPDO_COMMUNICATION_BASE,
    TPDO_MAPPING_BASE,
    sensor_object_dictionary,
)
from drivers.canbus.read_ahead import ReadAheadSerial
from drivers.canbus.readings import ForceReading, LinkReading, WrenchReading
from drivers.canbus.units import (
    force_n_from_counts,
    link_angle_rad_from_counts,
    wrench_from_counts,
)
from drivers.joint_bus import BusError

CIA406_ENCODER_PROFILE = 0x0196
CIA404_MEASURING_DEVICE_PROFILE = 0x0194
CIA406_SINGLE_TURN_ABSOLUTE = 0x0001  # 0x1000 bits 16-31: the count wraps once per turn
POSITION_VALUE_MAPPING = 0x6004_0020  # 0x6004 position value, 32 bits
AI_PROCESS_VALUE_MAPPING = 0x9130_0120  # 0x9130:01 AI input PV, 32 bits
CIA303_NEWTON = 0x21  # unit code in byte 2 of 0x6131 (CiA 303-2)
# A force/torque sensor's moments: CiA 303-2 has no code of its own for the newton metre; the
# joule (0x23) has its SI dimension and is what the emulated sensor reports (see its EDS).
CIA303_NEWTON_METRE = 0x23
# Force/torque sensor: its two TPDOs map the 16-bit AI PVs 0x7130:1-3 (forces), :4-6 (moments)
FORCE_TORQUE_MAPPINGS = (
    (0x7130_0110, 0x7130_0210, 0x7130_0310),
    (0x7130_0410, 0x7130_0510, 0x7130_0610),
)
_FORCE_TORQUE_CHANNELS = 6
_INT16x3 = struct.Struct("<hhh")

_NMT_RESET_COMMUNICATION = 0x82
_NMT_START = 0x01
_NMT_STOP = 0x02
_NMT_ENTER_PRE_OPERATIONAL = 0x80
_HEARTBEAT_OPERATIONAL = 0x05
_HEARTBEAT_BOOTUP = 0x00
_HEARTBEAT_PRE_OPERATIONAL = 0x7F
_PDO_COB_ID_INVALID = 1 << 31
_STANDARD_ID_MASK = 0x7FF
_HEARTBEAT_BASE = 0x700
_TPDO_COB_ID_BASES = (0x180, 0x280, 0x380, 0x480)
_INT32 = struct.Struct("<i")
_INT32_SPAN = 2**32
_UNKNOWN_STATE = 0xFF
_NOTIFIER_POLL_S = 0.005
# CiA 301 frame lengths canopen's handlers rely on, by function code (COB-ID & 0x780), for
# the COB-IDs a RemoteNode subscribes to: NMT 0x000, EMCY 0x080+id, SDO 0x580+id, 0x700+id.
_FUNCTION_CODE_MASK = 0x780
_MIN_FRAME_BYTES = {
    0x000: 2,  # NMT command: command specifier, node ID
    0x080: 8,  # EMCY: error code, error register, 5 bytes manufacturer data
    0x580: 8,  # SDO response
    0x700: 1,  # heartbeat / boot-up: the state byte
}
_MAX_FRAMES_PER_DRAIN = 1024


class CanDeviceError(BusError):
    """A CAN sensor node could not be opened or read (the message names node and bus)."""


@dataclass
class _Device:
    """One node as the reader knows it (configuration plus what open() learned)."""

    label: str
    config: LinkEncoderConfig | ForceSensorConfig | ForceTorqueSensorConfig
    node: canopen.RemoteNode
    tpdo_cob_id: int = 0
    tpdo_cob_ids: tuple[int, ...] = ()  # every TPDO the node answers a SYNC with
    single_turn: bool = False
    newtons_per_count: float = 1.0
    si_per_count: np.ndarray | None = None  # force/torque sensor: per channel, N or N m

    @property
    def is_encoder(self) -> bool:
        return isinstance(self.config, LinkEncoderConfig)

    @property
    def is_force_torque(self) -> bool:
        return isinstance(self.config, ForceTorqueSensorConfig)


class LinkEncoderReader:
    """Reads the link encoders (and the optional force sensor) on one CAN bus; see module doc.

    bus: a python-can bus, built by the caller from configuration; the reader owns it from
    now on and shuts it down in `close()`.
    clock: the time base of `sync_time_s`, ages and heartbeat timing (default
    time.monotonic; a lock-step loop passes its simulated clock so the data are deterministic).
    Deadlines (`collect`'s timeout, open's waits) always use real time.
    """

    def __init__(
        self,
        bus: can.BusABC,
        encoders: Sequence[LinkEncoderConfig],
        *,
        force_sensor: ForceSensorConfig | None = None,
        force_torque_sensors: Sequence[ForceTorqueSensorConfig] = (),
        clock: Callable[[], float] = time.monotonic,
        bus_description: str | None = None,
        sdo_timeout_s: float = 0.3,
        boot_timeout_s: float = 1.0,
        heartbeat_timeout_factor: float = 3.0,
    ) -> None:
        configs: list[LinkEncoderConfig | ForceSensorConfig | ForceTorqueSensorConfig] = list(
            encoders
        )
        if not configs:
            raise ValueError("LinkEncoderReader needs at least one LinkEncoderConfig")
        if force_sensor is not None:
            configs.append(force_sensor)
        configs.extend(force_torque_sensors)
        node_ids = [config.node_id for config in configs]
        if len(set(node_ids)) != len(node_ids):
            raise ValueError(f"CAN sensor node IDs must be distinct, got {node_ids}")
        if heartbeat_timeout_factor <= 1.0:
            raise ValueError(
                "heartbeat_timeout_factor must be > 1 (missed beats tolerated), "
                f"got {heartbeat_timeout_factor}"
            )
        self._bus = bus
        self._fd = _selectable_fileno(bus)
        self._read_ahead = _read_ahead_port(bus)
        self._clock = clock
        self.bus_description = bus_description or f"{type(bus).__name__} ({bus.channel_info})"
        self._sdo_timeout_s = sdo_timeout_s
        self._boot_timeout_s = boot_timeout_s
        self._network = canopen.Network(bus)  # no connect(): we own the receive path
        self._object_dictionary = sensor_object_dictionary()
        self.encoder_configs: tuple[LinkEncoderConfig, ...] = tuple(encoders)
        self.force_sensor_config = force_sensor
        self.force_torque_configs: tuple[ForceTorqueSensorConfig, ...] = tuple(force_torque_sensors)
        self._devices: list[_Device] = []
        for index, config in enumerate(configs):
            node = canopen.RemoteNode(config.node_id, self._object_dictionary)
            node.sdo.RESPONSE_TIMEOUT = sdo_timeout_s
            self._network.add_node(node)
            node.nmt.add_heartbeat_callback(functools.partial(self._on_heartbeat, index))
            node.emcy.add_callback(functools.partial(self._on_emcy, index))
            if isinstance(config, LinkEncoderConfig):
                label = f"link encoder node {config.node_id} (joint {index})"
            elif isinstance(config, ForceTorqueSensorConfig):
                label = f"force/torque sensor node {config.node_id} ({config.label})"
            else:
                label = f"force sensor node {config.node_id}"
            self._devices.append(_Device(label=label, config=config, node=node))

        n_devices = len(self._devices)
        self._n_encoders = len(self.encoder_configs)
        self._tpdo_device: dict[int, int] = {}
        self._tpdo_part: dict[int, int] = {}  # COB-ID -> which of its device's TPDOs (0, 1)
        # Force/torque sensors: devices _ft_first.. ; both TPDOs of a SYNC make an answer.
        n_ft = len(self.force_torque_configs)
        self._ft_first = n_devices - n_ft
        self._ft_parts = np.zeros(n_devices, dtype=np.int64)  # bit per TPDO received
        self._ft_answer_raw = np.zeros((n_ft, _FORCE_TORQUE_CHANNELS), dtype=np.int64)
        self._ft_raw = np.zeros((n_ft, _FORCE_TORQUE_CHANNELS), dtype=np.int64)
        self._ft_offsets = [
            (np.asarray(c.force_offset_n, dtype=float), np.asarray(c.torque_offset_nm, dtype=float))
            for c in self.force_torque_configs
        ]
        # Per-device state (index = position in self._devices).
        self._answered = np.zeros(n_devices, dtype=bool)
        self._answer_raw = np.zeros(n_devices, dtype=np.int64)
        self._raw = np.zeros(n_devices, dtype=np.int64)
        self._have_raw = np.zeros(n_devices, dtype=bool)
        self._unchanged = np.zeros(n_devices, dtype=np.int64)
        self._last_valid_time = np.full(n_devices, -np.inf)
        self._nmt_state = np.full(n_devices, _UNKNOWN_STATE, dtype=np.int64)
        self._state_names: tuple[str, ...] | None = None  # of _nmt_state, until it changes
        self._last_heartbeat_time = np.full(n_devices, -np.inf)
        self._heartbeat_timeout_s = np.array(
            [
                heartbeat_timeout_factor * config.heartbeat_ms / 1000.0
                if config.heartbeat_ms
                else np.inf
                for config in configs
            ]
        )
        self._stale_after_s = np.array([config.stale_after_s for config in configs])
        encoder_configs = self.encoder_configs
        self._counts_per_rev = np.array([c.counts_per_rev for c in encoder_configs], dtype=np.int64)
        self._direction = np.array([c.direction for c in encoder_configs], dtype=np.int64)
        self._offset_rad = np.array([c.offset_rad for c in encoder_configs])
        self._single_turn = np.zeros(self._n_encoders, dtype=bool)
        self._counts = np.zeros(self._n_encoders, dtype=np.int64)  # read on through the wrap
        self._n_answered = 0
        self._sync_time_s = math.nan
        self._sync_outstanding = False
        self._events: list[str] = []
        self._heartbeat_seen = threading.Condition()
        self._states_since_mark: list[list[int]] = [[] for _ in range(n_devices)]
        self._notifier: can.Notifier | None = None
        self._configuring: set[int] = set()
        self._is_open = False
        self._closed = False

    # --- lifecycle -------------------------------------------------------------------------
    @property
    def is_open(self) -> bool:
        return self._is_open

    def open(self) -> None:
        """Bring every node up (see module doc); raises CanDeviceError naming the node."""
        if self._closed:
            raise CanDeviceError(f"the reader on {self.bus_description} was closed")
        with self._configuration_phase():
            for index in range(len(self._devices)):
                self._bring_up(index)
        self._drain()
        self._events.clear()
        self._is_open = True

    def recover_node(self, node_id: int) -> None:
        """Bring one node up again (e.g. after it rebooted: boot-up seen, Pre-operational)."""
        index = self._device_index(node_id)
        with self._configuration_phase():
            self._bring_up(index)
        self._drain()

    def close(self, *, nmt_command: str | None = None) -> None:
        """Release the bus; first send NMT "PRE-OPERATIONAL" or "STOPPED" to every node if asked.

        Safe to call twice.
        """
        commands = {None: None, "PRE-OPERATIONAL": _NMT_ENTER_PRE_OPERATIONAL, "STOPPED": _NMT_STOP}
        if nmt_command not in commands:
            raise ValueError(
                f"nmt_command must be None, 'PRE-OPERATIONAL' or 'STOPPED', got {nmt_command!r}"
            )
        if self._closed:
            return
        self._closed = True
        self._is_open = False
        try:
            self._stop_notifier()
            command = commands[nmt_command]
            if command is not None:
                for device in self._devices:
                    with contextlib.suppress(can.CanError):
                        device.node.nmt.send_command(command)
        finally:
            self._bus.shutdown()

    def __enter__(self) -> LinkEncoderReader:
        self.open()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    # --- per tick --------------------------------------------------------------------------
    def send_sync(self) -> None:
        """Put one SYNC on the bus now (after taking older frames off the bus)."""
        if not self._is_open:
            raise CanDeviceError(f"send_sync() on {self.bus_description} before open()")
        self._drain()
        self._answered[:] = False
        self._ft_parts[:] = 0
        self._n_answered = 0
        self._sync_time_s = self._clock()
        self._sync_outstanding = True
        self._network.sync.transmit()

    def collect(self, timeout_s: float) -> LinkReading:
        """The answers to the last SYNC: returns when all nodes answered or after timeout_s."""
        if not self._sync_outstanding:
            raise CanDeviceError(f"collect() on {self.bus_description} without send_sync() first")
        n_devices = len(self._devices)
        deadline = time.monotonic() + timeout_s
        overdue_frames = 0
        while self._n_answered < n_devices:
            remaining = deadline - time.monotonic()
            if remaining <= 0.0:
                # Past the deadline only frames already received count, and only so many:
                # a flooded bus must not keep collect() from returning.
                overdue_frames += 1
                if overdue_frames > _MAX_FRAMES_PER_DRAIN:
                    break
            msg = self._receive(deadline)
            if msg is None:
                break
            self._dispatch(msg)
        self._sync_outstanding = False
        return self._build_reading()

    def read(self, timeout_s: float) -> LinkReading:
        """send_sync() then collect(timeout_s) (for a loop that has nothing to do in between)."""
        self.send_sync()
        return self.collect(timeout_s)

    # --- receive path (no thread) ----------------------------------------------------------
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
        for _ in range(_MAX_FRAMES_PER_DRAIN):
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
        for _ in range(_MAX_FRAMES_PER_DRAIN):
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
        booted = state == _HEARTBEAT_BOOTUP
        if booted:
            state = _HEARTBEAT_PRE_OPERATIONAL  # a booted node is Pre-operational
        if index in self._configuring:
            pass  # the boot-up and state changes that open()/recover_node() caused
        elif booted:
            self._events.append(
                f"{device.label}: boot-up frame (the node restarted; it is Pre-operational "
                "and has its default configuration: call recover_node)"
            )
        elif state != previous and previous != _UNKNOWN_STATE:
            self._events.append(
                f"{device.label}: NMT state {_state_name(previous)} -> {_state_name(state)}"
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

    def _build_reading(self) -> LinkReading:
        now_s = self._sync_time_s
        answered = self._answered
        changed = answered & self._have_raw & (self._answer_raw != self._raw)
        repeated = answered & self._have_raw & ~changed
        self._unchanged += repeated  # a repeated count counts on, a new one starts again
        self._unchanged[answered & ~repeated] = 0
        n = self._n_encoders
        new, before = self._answer_raw[:n], self._raw[:n]
        step = (new - before + _INT32_SPAN // 2) % _INT32_SPAN - _INT32_SPAN // 2
        self._counts = np.where(
            answered[:n], np.where(self._have_raw[:n], self._counts + step, new), self._counts
        )
        self._raw = np.where(answered, self._answer_raw, self._raw)
        self._have_raw |= answered
        self._last_valid_time[answered] = now_s
        age_s = now_s - self._last_valid_time
        stale = age_s > self._stale_after_s
        heartbeat_age_s = self._clock() - self._last_heartbeat_time
        heartbeat_lost = heartbeat_age_s > self._heartbeat_timeout_s
        states = self._state_names
        if states is None:
            states = self._state_names = tuple(_state_name(int(s)) for s in self._nmt_state)

        angles = link_angle_rad_from_counts(
            self._counts,
            self._counts_per_rev,
            self._direction,
            self._offset_rad,
            self._single_turn,
        )
        angles = np.where(answered[:n], angles, np.nan)
        force = None
        if self.force_sensor_config is not None:
            device = self._devices[n]
            config = device.config
            assert isinstance(config, ForceSensorConfig)
            valid = bool(answered[n])
            force = ForceReading(
                force_n=(
                    force_n_from_counts(
                        int(self._raw[n]),
                        device.newtons_per_count,
                        config.direction,
                        config.offset_n,
                    )
                    if valid
                    else math.nan
                ),
                valid=valid,
                age_s=float(age_s[n]),
                stale=bool(stale[n]),
                raw=int(self._raw[n]),
                nmt_state=states[n],
                heartbeat_age_s=float(heartbeat_age_s[n]),
                heartbeat_lost=bool(heartbeat_lost[n]),
            )
        wrenches = tuple(
            self._wrench_reading(index, age_s, stale, states, heartbeat_age_s, heartbeat_lost)
            for index in range(self._ft_first, len(self._devices))
        )
        events = tuple(self._events)
        self._events.clear()
        return LinkReading(
            sync_time_s=now_s,
            angles_rad=angles,
            valid=answered[:n].copy(),
            age_s=age_s[:n],
            stale=stale[:n],
            raw_counts=self._raw[:n].copy(),
            raw_changed=changed[:n],
            unchanged_count=self._unchanged[:n].copy(),
            nmt_state=states[:n],
            heartbeat_age_s=heartbeat_age_s[:n],
            heartbeat_lost=heartbeat_lost[:n],
            force=force,
            events=events,
            wrenches=wrenches,
        )

    def _wrench_reading(
        self,
        index: int,
        age_s: np.ndarray,
        stale: np.ndarray,
        states: tuple[str, ...],
        heartbeat_age_s: np.ndarray,
        heartbeat_lost: np.ndarray,
    ) -> WrenchReading:
        device = self._devices[index]
        config = device.config
        assert isinstance(config, ForceTorqueSensorConfig) and device.si_per_count is not None
        sensor = index - self._ft_first
        valid = bool(self._answered[index])
        if valid:
            self._ft_raw[sensor] = self._ft_answer_raw[sensor]
            force_offset_n, torque_offset_nm = self._ft_offsets[sensor]
            force, torque = wrench_from_counts(
                self._ft_raw[sensor], device.si_per_count, force_offset_n, torque_offset_nm
            )
        else:
            force = torque = np.full(3, np.nan)
        return WrenchReading(
            label=config.label,
            force_n=force,
            torque_nm=torque,
            valid=valid,
            age_s=float(age_s[index]),
            stale=bool(stale[index]),
            raw=self._ft_raw[sensor].copy(),
            nmt_state=states[index],
            heartbeat_age_s=float(heartbeat_age_s[index]),
            heartbeat_lost=bool(heartbeat_lost[index]),
        )

    # --- configuration (canopen, Notifier running) -----------------------------------------
    @contextlib.contextmanager
    def _configuration_phase(self) -> Iterator[None]:
        self._notifier = can.Notifier(self._bus, self._network.listeners, timeout=_NOTIFIER_POLL_S)
        try:
            yield
        finally:
            self._stop_notifier()

    def _stop_notifier(self) -> None:
        if self._notifier is not None:
            self._notifier.stop(timeout=1.0)
            self._notifier = None

    def _error(self, device: _Device, problem: str) -> CanDeviceError:
        return CanDeviceError(f"{device.label} on {self.bus_description}: {problem}")

    def _bring_up(self, index: int) -> None:
        self._configuring.add(index)
        try:
            self._configure(index)
        finally:
            self._configuring.discard(index)

    def _configure(self, index: int) -> None:
        device = self._devices[index]
        self._tpdo_device = {cob: i for cob, i in self._tpdo_device.items() if i != index}
        self._tpdo_part = {cob: p for cob, p in self._tpdo_part.items() if cob in self._tpdo_device}
        self._reset_communication(index)
        config = device.config
        if isinstance(config, ForceTorqueSensorConfig):
            self._check_force_torque_sensor(device)
            device.tpdo_cob_ids = (
                self._configure_tpdo(index, config.force_tpdo, FORCE_TORQUE_MAPPINGS[0]),
                self._configure_tpdo(index, config.torque_tpdo, FORCE_TORQUE_MAPPINGS[1]),
            )
            if device.tpdo_cob_ids[0] == device.tpdo_cob_ids[1]:
                raise self._error(device, "its two TPDOs use the same COB-ID")
        else:
            if device.is_encoder:
                self._check_encoder(index)
                expected_mapping = POSITION_VALUE_MAPPING
            else:
                self._check_force_sensor(device)
                expected_mapping = AI_PROCESS_VALUE_MAPPING
            device.tpdo_cob_id = self._configure_tpdo(index, config.tpdo, (expected_mapping,))
            device.tpdo_cob_ids = (device.tpdo_cob_id,)
        self._sdo_write(device, 0x1017, 0, device.config.heartbeat_ms, "heartbeat time 0x1017")
        self._start(index)
        self._reset_tracking(index)

    def _reset_communication(self, index: int) -> None:
        device = self._devices[index]
        self._mark_states(index)
        device.node.nmt.send_command(_NMT_RESET_COMMUNICATION)
        if not self._wait_for_state(index, _HEARTBEAT_BOOTUP, self._boot_timeout_s):
            node_id = device.config.node_id
            raise self._error(
                device,
                f"no boot-up frame (0x{_HEARTBEAT_BASE + node_id:03X} [00]) within "
                f"{self._boot_timeout_s} s after NMT reset communication; is the node powered, "
                f"is its node ID {node_id} and does the bitrate match?",
            )

    def _read_profile(self, device: _Device) -> tuple[int, int, int]:
        device_type = self._sdo_read(device, 0x1000, 0, "device type 0x1000")
        return device_type, device_type & 0xFFFF, device_type >> 16

    def _check_encoder(self, index: int) -> None:
        device = self._devices[index]
        config = device.config
        assert isinstance(config, LinkEncoderConfig)
        device_type, profile, encoder_type = self._read_profile(device)
        if profile != CIA406_ENCODER_PROFILE:
            raise self._error(
                device,
                f"device type 0x{device_type:08X} is profile CiA {profile}, not a CiA 406 "
                "encoder (expected low 16 bits 0x0196)",
            )
        device.single_turn = encoder_type == CIA406_SINGLE_TURN_ABSOLUTE
        self._single_turn[index] = device.single_turn
        units_per_rev = self._sdo_read(device, 0x6001, 0, "units per revolution 0x6001")
        if units_per_rev != config.counts_per_rev:
            raise self._error(
                device,
                f"resolution mismatch: the node reports {units_per_rev} counts/rev (0x6001) but "
                f"the configuration says {config.counts_per_rev}; fix the configuration or the "
                "encoder's scaling",
            )

    def _check_force_sensor(self, device: _Device) -> None:
        self._require_measuring_device(device)
        device.newtons_per_count = self._si_per_count(device, 1, CIA303_NEWTON, "newton")

    def _check_force_torque_sensor(self, device: _Device) -> None:
        """CiA 404 with six channels: newton on 1-3, newton metre on 4-6; their resolutions."""
        self._require_measuring_device(device)
        channels = self._sdo_read(device, 0x6131, 0, "number of AI channels 0x6131:00")
        if channels < _FORCE_TORQUE_CHANNELS:
            raise self._error(
                device, f"has {channels} analogue inputs (0x6131:00); a force/torque sensor has 6"
            )
        device.si_per_count = np.array(
            [self._si_per_count(device, channel, CIA303_NEWTON, "newton") for channel in (1, 2, 3)]
            + [
                self._si_per_count(device, channel, CIA303_NEWTON_METRE, "newton metre")
                for channel in (4, 5, 6)
            ]
        )

    def _require_measuring_device(self, device: _Device) -> None:
        device_type, profile, _ = self._read_profile(device)
        if profile != CIA404_MEASURING_DEVICE_PROFILE:
            raise self._error(
                device,
                f"device type 0x{device_type:08X} is profile CiA {profile}, not a CiA 404 "
                "measuring device (expected low 16 bits 0x0194)",
            )

    def _si_per_count(self, device: _Device, channel: int, unit_code: int, unit: str) -> float:
        """One analogue input's resolution from 0x6131 (unit, prefix) and 0x6132 (digits)."""
        code = self._sdo_read(device, 0x6131, channel, f"AI physical unit 0x6131:{channel:02X}")
        if (code >> 16) & 0xFF != unit_code:
            raise self._error(
                device,
                f"physical unit 0x{code:08X} (0x6131:{channel:02X}) is not {unit} (CiA 303-2 "
                f"unit code 0x{unit_code:02X} in byte 2)",
            )
        prefix_exponent = int.from_bytes(bytes([code >> 24]), "little", signed=True)
        digits = self._sdo_read(device, 0x6132, channel, f"AI decimal digits 0x6132:{channel:02X}")
        return 10.0 ** (prefix_exponent - digits)

    def _configure_tpdo(self, index: int, number: int, expected: tuple[int, ...]) -> int:
        """Check TPDO `number`'s mapping starts with `expected`, enable the TPDO if its COB-ID
        is marked invalid, set transmission type 1 (CiA 301 0x18xx/0x1Axx); its COB-ID."""
        device = self._devices[index]
        communication = TPDO_COMMUNICATION_BASE + number - 1
        mapping = TPDO_MAPPING_BASE + number - 1
        n_mapped = self._sdo_read(device, mapping, 0, f"TPDO{number} mapping 0x{mapping:04X}:00")
        for entry, expected_mapping in enumerate(expected, start=1):
            mapped = 0
            if n_mapped >= entry:
                mapped = self._sdo_read(
                    device, mapping, entry, f"TPDO{number} mapping entry {entry}"
                )
            if mapped != expected_mapping:
                raise self._error(
                    device,
                    f"TPDO{number} maps 0x{mapped:08X} as entry {entry} "
                    f"(0x{mapping:04X}:{entry:02X}), expected 0x{expected_mapping:08X}; "
                    "configure the node's mapping or set the "
                    "TPDO number in the configuration to the TPDO that carries it",
                )
        cob_id = self._sdo_read(device, communication, 1, f"TPDO{number} COB-ID")
        if cob_id & _PDO_COB_ID_INVALID:
            cob_id &= ~_PDO_COB_ID_INVALID
            self._sdo_write(device, communication, 1, cob_id, f"TPDO{number} COB-ID (enable)")
        if self._sdo_read(device, communication, 2, f"TPDO{number} transmission type") != 1:
            self._sdo_write(device, communication, 2, 1, f"TPDO{number} transmission type 1")
        cob_id &= _STANDARD_ID_MASK
        if cob_id != _TPDO_COB_ID_BASES[number - 1] + device.config.node_id:
            self._events.append(
                f"{device.label}: TPDO{number} uses the non-default COB-ID 0x{cob_id:03X}"
            )
        clash = self._tpdo_device.get(cob_id)
        if clash is not None:
            raise self._error(
                device,
                f"TPDO COB-ID 0x{cob_id:03X} is also used by {self._devices[clash].label}",
            )
        return cob_id

    def _start(self, index: int) -> None:
        """NMT start, then wait for a heartbeat that says Operational (if heartbeats are on)."""
        device = self._devices[index]
        heartbeat_ms = device.config.heartbeat_ms
        self._mark_states(index)
        device.node.nmt.send_command(_NMT_START)
        if heartbeat_ms:
            wait_s = max(3.0 * heartbeat_ms / 1000.0, self._boot_timeout_s)
            if not self._wait_for_state(index, _HEARTBEAT_OPERATIONAL, wait_s):
                seen = [hex(state) for state in self._states_since_mark[index]]
                raise self._error(
                    device,
                    f"no heartbeat saying Operational (0x05) within {wait_s:.3g} s after NMT "
                    f"start (heartbeat states seen: {seen or 'none'})",
                )
        else:
            self._nmt_state[index] = _UNKNOWN_STATE  # no heartbeat: the state is not monitored
            self._state_names = None
        for part, cob_id in enumerate(device.tpdo_cob_ids):
            self._tpdo_device[cob_id] = index
            self._tpdo_part[cob_id] = part

    def _reset_tracking(self, index: int) -> None:
        self._have_raw[index] = False
        self._unchanged[index] = 0
        self._last_valid_time[index] = -np.inf
        self._answered[index] = False

    def _mark_states(self, index: int) -> None:
        with self._heartbeat_seen:
            self._states_since_mark[index] = []

    def _wait_for_state(self, index: int, state: int, timeout_s: float) -> bool:
        deadline = time.monotonic() + timeout_s
        with self._heartbeat_seen:
            while state not in self._states_since_mark[index]:
                remaining = deadline - time.monotonic()
                if remaining <= 0.0:
                    return False
                self._heartbeat_seen.wait(remaining)
        return True

    def _sdo_variable(self, device: _Device, index: int, subindex: int) -> canopen.sdo.SdoVariable:
        variable = self._object_dictionary.get_variable(index, subindex)
        if variable is None:
            raise KeyError(f"0x{index:04X}:{subindex:02X} missing from sensor_object_dictionary()")
        return canopen.sdo.SdoVariable(device.node.sdo, variable)

    def _sdo_read(self, device: _Device, index: int, subindex: int, what: str) -> int:
        with self._sdo_errors(device, f"reading {what}"):
            return int(self._sdo_variable(device, index, subindex).raw)
        raise AssertionError("unreachable")  # _sdo_errors always raises on failure

    def _sdo_write(self, device: _Device, index: int, subindex: int, value: int, what: str) -> None:
        with self._sdo_errors(device, f"writing {what}"):
            self._sdo_variable(device, index, subindex).raw = value

    @contextlib.contextmanager
    def _sdo_errors(self, device: _Device, action: str) -> Iterator[None]:
        try:
            yield
        except canopen.SdoAbortedError as error:
            raise CanDeviceError(
                f"{device.label} on {self.bus_description}: {action} refused: {error}"
            ) from None
        except canopen.SdoCommunicationError as error:
            raise CanDeviceError(
                f"{device.label} on {self.bus_description}: no SDO answer {action} within "
                f"{self._sdo_timeout_s} s ({error})"
            ) from None

    def _device_index(self, node_id: int) -> int:
        for index, device in enumerate(self._devices):
            if device.config.node_id == node_id:
                return index
        known = [device.config.node_id for device in self._devices]
        raise ValueError(
            f"node {node_id} is not configured on {self.bus_description} (known: {known})"
        )


def _selectable_fileno(bus: can.BusABC) -> int | None:
    """The bus's file descriptor if it has one to select() on (python-can's convention, as its
    Notifier uses it), else None."""
    try:
        fd = bus.fileno()
    except (NotImplementedError, can.CanError, OSError, ValueError):
        return None
    return fd if isinstance(fd, int) and fd >= 0 else None


def _read_ahead_port(bus: can.BusABC) -> ReadAheadSerial | None:
    """The read-ahead serial port under python-can's slcan bus, if it has one
    (drivers/canbus/read_ahead.py)."""
    port = getattr(bus, "serialPortOrig", None)
    return port if isinstance(port, ReadAheadSerial) else None


def _state_name(state: int) -> str:
    if state == _UNKNOWN_STATE:
        return "UNKNOWN"
    return NMT_STATES.get(state, f"0x{state:02X}")
