"""A deterministic CiA 301 slave for the emulator: NMT, heartbeat, SDO server, SYNC -> TPDO.

A pure frame handler: `handle(msg, now_s)` returns the frames the node puts on the bus in
answer to one frame, `poll(now_s)` the frames it sends on its own (boot-up, heartbeat, event
timer TPDO). Time is only the caller's `now_s` (the emulator's clock); the node owns no thread
and no timer, so a lock-step emulator gets the same frames for the same inputs every run.

CiA 301 behaviour implemented (sources: CiA 301 services as documented in the Beckhoff FC5101,
Inovance MD38CAN2 and Datalogic AMT58 manuals, and CANopenNode's `minimal_project.xdd`):
- NMT (0x000 [cs, node or 0]): start 0x01 -> Operational, stop 0x02 -> Stopped, 0x80 ->
  Pre-operational, reset node 0x81 (every object back to its default) and reset
  communication 0x82 (objects 0x1000-0x1FFF back to their defaults). After a reset, and when
  its power returns (fault "dead" cleared), the node initialises for `bootup_delay_s` (default
  `DEFAULT_BOOTUP_DELAY_S`): it sends nothing and ignores every frame, then sends its boot-up
  frame 0x700+id [0x00] and is Pre-operational. A node made by the emulator was powered before
  anyone listened: its boot-up goes out on the first call. A real node takes milliseconds to
  restart, so its boot-up always comes after the command; a master that sends the reset and
  then starts waiting for the boot-up (canopen's `nmt.wait_for_bootup()`) relies on that.
  `bootup_delay_s=0` answers at once, in the reply to the command itself.
- Heartbeat 0x700+id [state] every 0x1017 ms (0 = off), states 0x04/0x05/0x7F, and at once on
  an NMT state change (as CANopenNode's CO_NMT_process does; the period restarts from there).
  A heartbeat that falls due while the caller is not polling is skipped, not sent in a burst.
- SDO server (0x600+id -> 0x580+id) in Pre-operational and Operational, not in Stopped.
- TPDO1 (COB-ID in 0x1800:01, bit 31 = invalid) only in Operational. Transmission type
  (0x1800:02): 0 = on SYNC when the value changed, 1..240 = every n-th SYNC, 254/255 = every
  0x1800:05 ms (event timer) on the caller's clock. Types 241..253 are refused (abort
  0x06090030). The inhibit time (0x1800:03) and SYNC start value (0x1800:06) are stored but
  have no effect. The mapping (0x1A00) is static, read from the EDS.
- Node guarding (RTR on 0x700+id) and EMCY are not emulated.

Faults (`SensorFault`, mutable, looked at on every call):
- "dead": the node lost power: it sends nothing at all. Leaving "dead" is a power-on: all
  objects back to their defaults, boot-up frame after the boot-up delay, Pre-operational (the
  master must configure and start it again, as with a real node whose supply came back).
- "stale": a hung counter: the process value stays at the last value the node sampled before
  the fault began; NMT, SDO and heartbeat keep working.
- "noisy": zero-mean Gaussian noise of `noise_counts_rms` (in the device's raw units) is added
  before rounding, from a numpy Generator seeded by `seed` (deterministic).

The process value a node serves (nominal noise, faults, rounding) is in `process_value.py`,
the TPDO (mapping, SYNC and event-timer frames, its communication parameters) in `tpdo.py`.
"""

from __future__ import annotations

import abc
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import can
import numpy as np

from sim_backend.canbus.cia301 import (
    COMMUNICATION_AREA,
    HEARTBEAT_COB_ID_BASE,
    NMT_COB_ID,
    SDO_REQUEST_COB_ID_BASE,
    SDO_RESPONSE_COB_ID_BASE,
    SYNC_COB_ID,
    TRANSMISSION_EVENT_MANUFACTURER,
    NmtCommand,
    NmtState,
)
from sim_backend.canbus.object_store import ObjectStore
from sim_backend.canbus.process_value import (
    FAULT_MODES,
    ProcessValue,
    SensorFault,
    SensorFaultCounts,
    wrap_int32,
)
from sim_backend.canbus.sdo_server import SdoServer
from sim_backend.canbus.tpdo import TPDO_COMMUNICATION, TpdoProducer, transmission_type_refusal
from sim_backend.normal_stream import NormalStream

__all__ = [
    "DEFAULT_BOOTUP_DELAY_S",
    "FAULT_MODES",
    "CanopenSlave",
    "SensorFault",
    "SensorFaultCounts",
    "wrap_int32",
]

# How long an emulated node initialises after an NMT reset (or when its power returns) before
# it sends its boot-up frame. CiA 301 sets no figure; a device restarts its communication stack
# in milliseconds (a full application reset may take longer). What matters for a master is that
# the boot-up comes after the command, not with it. Measured with canopen's wait_for_bootup()
# right after the reset, over the emulated SLCAN adapter on this 2-core machine with two
# busy-loop processes as load: 7 of 200 waits missed the boot-up with no delay, 0 of 200 with
# 2, 5 and 10 ms; with a client that spins (python-can slcan timeout 0) 1 of 200 missed it at
# 5 ms. 10 ms leaves a descheduled master room to start waiting.
DEFAULT_BOOTUP_DELAY_S = 0.010

_HEARTBEAT_TIME = 0x1017


def _to_microseconds(now_s: float) -> int:
    # Integer time avoids 0.1 != 20 * 0.005 style misses in the heartbeat schedule.
    return round(now_s * 1_000_000)


class CanopenSlave(ProcessValue, TpdoProducer, abc.ABC):
    """Base of the emulated nodes; a subclass supplies the process value (`_ideal_raw`).

    A subclass sets its own attributes before calling `super().__init__`, which powers the
    node on (and so calls `_reset_application`).
    """

    def __init__(
        self,
        node_id: int,
        eds_file: Path,
        *,
        process_value_object: tuple[int, int],
        heartbeat_ms: int,
        seed: int,
        tpdo_transmission_type: int,
        serial_number: int,
        process_noise_rms: float = 0.0,
        bootup_delay_s: float = DEFAULT_BOOTUP_DELAY_S,
    ) -> None:
        if not (math.isfinite(bootup_delay_s) and bootup_delay_s >= 0.0):
            raise ValueError(f"bootup_delay_s must be a finite time >= 0 s, got {bootup_delay_s!r}")
        if not 1 <= node_id <= 127:
            raise ValueError(f"CANopen node ID must be 1..127, got {node_id}")
        if not 0 <= heartbeat_ms <= 0xFFFF:
            raise ValueError(
                f"heartbeat_ms must be 0..65535 (0x1017 is UNSIGNED16), got {heartbeat_ms}"
            )
        if transmission_type_refusal(tpdo_transmission_type) is not None:
            raise ValueError(
                "tpdo_transmission_type must be 0..240, 254 or 255 (CiA 301 0x1800:02), "
                f"got {tpdo_transmission_type}"
            )
        self.node_id = node_id
        self.fault = SensorFault()
        self._process_noise_rms = 0.0
        self._set_process_noise(process_noise_rms)
        self.fault_counts = SensorFaultCounts()
        self._store = ObjectStore(eds_file, node_id)
        self._store.set_default(_HEARTBEAT_TIME, 0, heartbeat_ms)
        self._store.set_default(TPDO_COMMUNICATION, 2, tpdo_transmission_type)
        self._store.set_default(0x1018, 4, serial_number)
        self._store.validate_writes(TPDO_COMMUNICATION, 1, self._validate_tpdo_cob_id)
        self._store.validate_writes(TPDO_COMMUNICATION, 2, transmission_type_refusal)
        self._store.on_read(*process_value_object, self._sample_raw)
        self._store.after_write = self._after_write
        self._sdo = SdoServer(self._store)
        self._normals = NormalStream(np.random.default_rng(seed))
        self._tpdo_objects, self._tpdo_struct = self._static_tpdo_mapping()
        self._tpdo_readers: list[Callable[[], Any]] | None = None

        self._heartbeat_cob_id = HEARTBEAT_COB_ID_BASE + node_id
        self._sdo_request_cob_id = SDO_REQUEST_COB_ID_BASE + node_id
        # The only frames `handle` acts on (any other one is ignored, or counted while dead)
        self.reacting_cob_ids = frozenset((NMT_COB_ID, SYNC_COB_ID, self._sdo_request_cob_id))
        self._sdo_response_cob_id = SDO_RESPONSE_COB_ID_BASE + node_id

        self._now_us = 0
        self._bootup_delay_us = round(bootup_delay_s * 1_000_000)
        self._powered = False
        self._boot_due_us: int | None = None  # initialising: the boot-up frame is due then
        self._state = NmtState.INITIALISING
        self._fault_mode_seen = "ok"
        self._last_sample_raw: int | None = None
        self._frozen_raw: int | None = None
        self._next_heartbeat_us: int | None = None
        self._next_event_us: int | None = None
        self._sync_count = 0
        self._last_transmitted: tuple[Any, ...] | None = None
        # TPDO communication parameters, cached from the store on every change.
        self._tpdo_cob_id = 0
        self._tpdo_enabled = False
        self._transmission_type = 1
        # Powered since before the emulator started: the boot-up goes out on the first call.
        self._power_on(delay_us=0)

    # --- public handler API ----------------------------------------------------------------
    @property
    def nmt_state(self) -> NmtState:
        """The node's NMT state (INITIALISING while it has no power)."""
        return self._state

    @property
    def powered(self) -> bool:
        """False while the node has no power (fault "dead"), as of its last call."""
        return self._powered

    @property
    def booting(self) -> bool:
        """True while the node initialises after a reset or power-on (it is silent)."""
        return self._powered and self._boot_due_us is not None

    def next_due_s(self) -> float | None:
        """When this node next sends on its own (boot-up, heartbeat, event timer), or None.

        An event loop can sleep until then instead of polling (the node's clock, seconds).
        """
        if not self._powered:
            return None
        if self._boot_due_us is not None:
            return self._boot_due_us * 1e-6
        due = [t for t in (self._next_heartbeat_us, self._event_due_us()) if t is not None]
        return min(due) * 1e-6 if due else None

    def handle(self, msg: can.Message, now_s: float) -> list[can.Message]:
        """Frames this node sends in answer to `msg` (seen on the bus at `now_s`)."""
        out = self._prologue(now_s)
        if not self._powered:
            self.fault_counts.frames_ignored_while_dead += 1
            return out
        if self._boot_due_us is not None:
            return out  # still initialising: deaf
        if msg.is_extended_id or msg.is_remote_frame or msg.is_error_frame:
            return out
        cob_id = msg.arbitration_id
        if cob_id == SYNC_COB_ID:
            if self._state == NmtState.OPERATIONAL:
                out.extend(self._on_sync())
        elif cob_id == self._sdo_request_cob_id:
            if self._state in (NmtState.PRE_OPERATIONAL, NmtState.OPERATIONAL):
                response = self._sdo.handle_request(msg.data)
                if response is not None:
                    out.append(self._frame(self._sdo_response_cob_id, response))
        elif cob_id == NMT_COB_ID:
            out.extend(self._on_nmt(msg.data))
        return out

    def poll(self, now_s: float) -> list[can.Message]:
        """Frames this node sends on its own by `now_s`: boot-up, heartbeat, event-timer TPDO."""
        out = self._prologue(now_s)
        if not self._powered or self._boot_due_us is not None:
            return out
        now_us = self._now_us
        if self._next_heartbeat_us is not None and now_us >= self._next_heartbeat_us:
            out.append(self._frame(self._heartbeat_cob_id, bytes([self._state])))
            self._next_heartbeat_us = self._advance(
                self._next_heartbeat_us, self._heartbeat_period_us()
            )
        if (
            self._next_event_us is not None
            and now_us >= self._next_event_us
            and self._transmission_type >= TRANSMISSION_EVENT_MANUFACTURER
        ):
            if self._state == NmtState.OPERATIONAL and self._tpdo_enabled:
                out.append(self._tpdo_frame(self._tpdo_values()))
            self._next_event_us = self._advance(self._next_event_us, self._event_period_us())
        return out

    def sample(self, now_s: float) -> int | None:
        """The raw process value a SYNC at `now_s` would latch (None while the node is dead):
        the same noise, fault and rounding, the same random draws as on the bus. For running the
        emulated robot in-process (sim_backend.direct), where no frames are exchanged."""
        self._prologue(now_s)
        if self.fault.mode == "dead":
            return None
        return self._sample_raw()

    # --- for subclasses --------------------------------------------------------------------
    @abc.abstractmethod
    def _ideal_raw(self) -> float:
        """Process value in the device's raw units before rounding, without faults."""

    def _reset_application(self) -> None:  # an optional hook
        """Device-specific state back to power-on (reset node / power cycle)."""

    def _on_object_written(self, index: int, subindex: int, value: Any) -> None:
        """A device object was written by SDO (after validation and storage); optional hook."""

    # --- NMT, power, faults ----------------------------------------------------------------
    def _prologue(self, now_s: float) -> list[can.Message]:
        self._now_us = _to_microseconds(now_s)
        mode = self.fault.mode
        if mode != self._fault_mode_seen:
            self.fault.check()
            if mode == "dead":
                self._powered = False
                self._state = NmtState.INITIALISING
            elif self._fault_mode_seen == "dead":
                self._power_on(delay_us=self._bootup_delay_us)
            if mode == "stale":
                if self._last_sample_raw is None:
                    self._sample_raw()
                self._frozen_raw = self._last_sample_raw
            else:
                self._frozen_raw = None
            self._fault_mode_seen = mode
        if self._powered and self._boot_due_us is not None and self._now_us >= self._boot_due_us:
            self._boot_due_us = None
            return [self._boot()]
        return []

    def _power_on(self, delay_us: int) -> None:
        self._store.reset()
        self._reset_application()
        self._sdo.reset()
        self._refresh_tpdo_cache()
        self._powered = True
        self._last_transmitted = None
        self._start_initialising(delay_us)

    def _start_initialising(self, delay_us: int) -> None:
        """Silent until the boot-up falls due, `delay_us` from now."""
        self._state = NmtState.INITIALISING
        self._next_heartbeat_us = None
        self._next_event_us = None
        self._boot_due_us = self._now_us + delay_us

    def _boot(self) -> can.Message:
        """Initialisation finished: boot-up frame, Pre-operational, timers restart from now."""
        self._state = NmtState.PRE_OPERATIONAL
        self._sdo.reset()
        self._sync_count = 0
        self._restart_heartbeat()
        self._restart_event_timer()
        return self._frame(self._heartbeat_cob_id, b"\x00")

    def _on_nmt(self, data: bytes | bytearray) -> list[can.Message]:
        if len(data) < 2 or data[1] not in (0, self.node_id):
            return []
        command = data[0]
        previous = self._state
        if command == NmtCommand.START:
            if previous != NmtState.OPERATIONAL:
                self._sync_count = 0
                self._last_transmitted = None
            self._state = NmtState.OPERATIONAL
        elif command == NmtCommand.STOP:
            self._state = NmtState.STOPPED
        elif command == NmtCommand.ENTER_PRE_OPERATIONAL:
            self._state = NmtState.PRE_OPERATIONAL
        elif command in (NmtCommand.RESET_NODE, NmtCommand.RESET_COMMUNICATION):
            if command == NmtCommand.RESET_NODE:
                self._store.reset()
                self._reset_application()
            else:
                self._store.reset(COMMUNICATION_AREA)
            self._refresh_tpdo_cache()
            self._start_initialising(self._bootup_delay_us)
            if self._bootup_delay_us == 0:
                self._boot_due_us = None
                return [self._boot()]
            return []
        if self._state != previous and self._heartbeat_period_us() > 0:
            # As CANopenNode does (CO_NMT_process): a state change is announced at once.
            self._restart_heartbeat()
            return [self._frame(self._heartbeat_cob_id, bytes([self._state]))]
        return []

    # --- timers ----------------------------------------------------------------------------
    def _heartbeat_period_us(self) -> int:
        return int(self._store.stored_value(_HEARTBEAT_TIME)) * 1000

    def _event_due_us(self) -> int | None:
        if self._transmission_type < TRANSMISSION_EVENT_MANUFACTURER:
            return None
        return self._next_event_us

    def _event_period_us(self) -> int:
        return int(self._store.stored_value(TPDO_COMMUNICATION, 5)) * 1000

    def _restart_heartbeat(self) -> None:
        period = self._heartbeat_period_us()
        self._next_heartbeat_us = self._now_us + period if period > 0 else None

    def _restart_event_timer(self) -> None:
        period = self._event_period_us()
        self._next_event_us = self._now_us + period if period > 0 else None

    def _advance(self, due_us: int, period_us: int) -> int | None:
        if period_us <= 0:
            return None
        due_us += period_us
        if due_us <= self._now_us:  # the caller skipped whole periods: do not burst
            due_us = self._now_us + period_us
        return due_us

    def _after_write(self, index: int, subindex: int, value: Any) -> None:
        if index == _HEARTBEAT_TIME:
            self._restart_heartbeat()
        elif index == TPDO_COMMUNICATION:
            self._refresh_tpdo_cache()
            if subindex == 2:
                self._sync_count = 0
                self._last_transmitted = None
            self._restart_event_timer()
        else:
            self._on_object_written(index, subindex, value)

    def _frame(self, cob_id: int, data: bytes) -> can.Message:
        # positional: timestamp, arbitration_id, is_extended_id, is_remote_frame,
        # is_error_frame, channel, dlc, data (keywords cost more than the frame)
        return can.Message(self._now_us * 1e-6, cob_id, False, False, False, None, None, data)
