"""Link encoders (CiA 406), an optional force sensor (CiA 404) and optional six-axis force/torque
sensors (CiA 404, six channels in two TPDOs) on CAN, read by SYNC -> TPDO.

Each tick the loop calls `send_sync()` (the SYNC frame 0x080 goes on the bus at once; every
node latches its value now) and then `collect(timeout_s)`, which reads the answering TPDOs
straight from the python-can bus with `bus.recv` up to the deadline and returns as soon as every
node has answered. No background thread decides what `collect()` returns, so a lock-step
experiment is deterministic. Frames that arrive before the SYNC (a TPDO too late for the
previous tick, heartbeats) are taken off the bus by `send_sync()` first, so a reading only
holds answers to THIS SYNC.

Units: counts -> radians in `units.link_angle_rad_from_counts` and PV -> N in
`units.force_n_from_counts`, nowhere else. The TPDO bytes are decoded as a little-endian INTEGER32
(CiA 406 v3.2; an UNSIGNED32 device sends the same bits), so negative link angles are negative.
A multi-turn count that passes the INTEGER32 range wraps (2**31 - 1 + 1 -> -2**31): an encoder's
count is read on through the wrap, each reading the last plus the difference modulo 2**32 (a
link never turns 2**31 counts, 2184 revolutions at 983,040 counts/rev, between two readings);
the first reading after `open()` is taken as it is.

The node bring-up (NMT, SDO checks, TPDO configuration) is in `node_bringup.py`, the
receive path (waiting on the bus, routing each frame) in `frame_receive.py`; this module holds
the reader's state, its lifecycle, the per-tick SYNC/collect and the reading built from the answers.
"""

from __future__ import annotations

import contextlib
import functools
import math
import threading
import time
from collections.abc import Callable, Sequence

import can
import canopen
import numpy as np

from drivers.canbus.config import ForceSensorConfig, ForceTorqueSensorConfig, LinkEncoderConfig
from drivers.canbus.frame_receive import (
    MAX_FRAMES_PER_DRAIN,
    FrameReceiver,
    read_ahead_port,
    selectable_fileno,
)
from drivers.canbus.node_bringup import NodeBringUp
from drivers.canbus.object_dictionary import sensor_object_dictionary
from drivers.canbus.readings import ForceReading, LinkReading, WrenchReading
from drivers.canbus.sensor_nodes import (
    FORCE_TORQUE_CHANNELS,
    UNKNOWN_STATE,
    CanDeviceError,
    SensorDevice,
    state_name,
)
from drivers.canbus.units import force_n_from_counts, link_angle_rad_from_counts, wrench_from_counts
from drivers.peer_wait import PeerWait

__all__ = ["CanDeviceError", "LinkEncoderReader"]

_NMT_STOP = 0x02
_NMT_ENTER_PRE_OPERATIONAL = 0x80
_INT32_SPAN = 2**32


class LinkEncoderReader(NodeBringUp, FrameReceiver):
    """Reads the link encoders (and the optional force sensor) on one CAN bus; see module doc.

    bus: a python-can bus, built by the caller from configuration; the reader owns it from
    now on and shuts it down in `close()`.
    encoders: may be none (a channel of force sensors only, or of the SYNC alone, which a
    lock-step emulator steps its plant on: a robot without link encoders).
    clock: the time base of `sync_time_s`, ages and heartbeat timing (default
    time.monotonic; a lock-step loop passes its simulated clock so the data are deterministic).
    Deadlines (`collect`'s timeout, open's waits) always use real time.
    patience: for nodes served by a process on this machine (an emulator in lock-step), the
    waits of `open()` for a node's boot-up and Operational heartbeat go on past their
    deadline while that process works (drivers/peer_wait.py), and an SDO transfer whose
    answer did not come within `sdo_timeout_s` (0.3 s, canopen's) is asked for again while it
    works; None (hardware): the deadline. `collect` keeps its timeout: a lock-step emulator
    has written a SYNC's TPDOs before it answers the sync read, which the bus collects first
    (`links_after_actuators`), so there is nothing left to wait for.
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
        patience: PeerWait | None = None,
    ) -> None:
        configs: list[LinkEncoderConfig | ForceSensorConfig | ForceTorqueSensorConfig] = list(
            encoders
        )
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
        self._fd = selectable_fileno(bus)
        self._read_ahead = read_ahead_port(bus)
        self._clock = clock
        self.bus_description = bus_description or f"{type(bus).__name__} ({bus.channel_info})"
        self._sdo_timeout_s = sdo_timeout_s
        self._patience = patience
        self._boot_timeout_s = boot_timeout_s
        self._network = canopen.Network(bus)  # no connect(): we own the receive path
        self._object_dictionary = sensor_object_dictionary()
        self.encoder_configs: tuple[LinkEncoderConfig, ...] = tuple(encoders)
        self.force_sensor_config = force_sensor
        self.force_torque_configs: tuple[ForceTorqueSensorConfig, ...] = tuple(force_torque_sensors)
        self._devices = self._add_nodes(configs, sdo_timeout_s)
        self._init_state(configs, heartbeat_timeout_factor)

    def _add_nodes(
        self,
        configs: Sequence[LinkEncoderConfig | ForceSensorConfig | ForceTorqueSensorConfig],
        sdo_timeout_s: float,
    ) -> list[SensorDevice]:
        """A canopen RemoteNode per sensor on the network, its heartbeat and EMCY handlers."""
        devices: list[SensorDevice] = []
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
            devices.append(SensorDevice(label=label, config=config, node=node))
        return devices

    def _init_state(
        self,
        configs: Sequence[LinkEncoderConfig | ForceSensorConfig | ForceTorqueSensorConfig],
        heartbeat_timeout_factor: float,
    ) -> None:
        """The per-device and per-SYNC state, allocated once (arrays indexed like `_devices`)."""
        n_devices = len(self._devices)
        self._n_encoders = len(self.encoder_configs)
        self._tpdo_device: dict[int, int] = {}
        self._tpdo_part: dict[int, int] = {}  # COB-ID -> which of its device's TPDOs (0, 1)
        # Force/torque sensors: devices _ft_first.. ; both TPDOs of a SYNC make an answer.
        n_ft = len(self.force_torque_configs)
        self._ft_first = n_devices - n_ft
        self._ft_parts = np.zeros(n_devices, dtype=np.int64)  # bit per TPDO received
        self._ft_answer_raw = np.zeros((n_ft, FORCE_TORQUE_CHANNELS), dtype=np.int64)
        self._ft_raw = np.zeros((n_ft, FORCE_TORQUE_CHANNELS), dtype=np.int64)
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
        self._nmt_state = np.full(n_devices, UNKNOWN_STATE, dtype=np.int64)
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
                if overdue_frames > MAX_FRAMES_PER_DRAIN:
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
            states = self._state_names = tuple(state_name(int(s)) for s in self._nmt_state)

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
