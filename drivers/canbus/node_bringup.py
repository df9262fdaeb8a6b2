"""Bringing the CAN sensor nodes up: NMT and SDO with canopen at `open()` and `recover_node()`.

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

`NodeBringUp` holds these steps for `LinkEncoderReader` (drivers/canbus/link_encoders.py), whose
state (devices, TPDO routing, heartbeat bookkeeping) they fill in; nothing here runs per tick.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator
from typing import TypeVar

import can
import canopen
import numpy as np

from drivers.canbus.config import ForceTorqueSensorConfig, LinkEncoderConfig
from drivers.canbus.object_dictionary import TPDO_COMMUNICATION_BASE, TPDO_MAPPING_BASE
from drivers.canbus.sensor_nodes import (
    FORCE_TORQUE_CHANNELS,
    HEARTBEAT_BOOTUP,
    HEARTBEAT_OPERATIONAL,
    UNKNOWN_STATE,
    CanDeviceError,
    SensorDevice,
)

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

_NMT_RESET_COMMUNICATION = 0x82
_NMT_START = 0x01
_PDO_COB_ID_INVALID = 1 << 31
_STANDARD_ID_MASK = 0x7FF
_HEARTBEAT_BASE = 0x700
_TPDO_COB_ID_BASES = (0x180, 0x280, 0x380, 0x480)
_NOTIFIER_POLL_S = 0.005

T = TypeVar("T")


class NodeBringUp:
    """The configuration phase of `LinkEncoderReader` (a mixin: it works on the reader's state).

    The python-can Notifier runs only inside `_configuration_phase()`, because canopen's SDO
    client waits for its answers on a queue; the per-tick path reads the bus itself.
    """

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

    def _error(self, device: SensorDevice, problem: str) -> CanDeviceError:
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
        if not self._wait_for_state(index, HEARTBEAT_BOOTUP, self._boot_timeout_s):
            node_id = device.config.node_id
            raise self._error(
                device,
                f"no boot-up frame (0x{_HEARTBEAT_BASE + node_id:03X} [00]) within "
                f"{self._boot_timeout_s} s after NMT reset communication; is the node powered, "
                f"is its node ID {node_id} and does the bitrate match?",
            )

    def _read_profile(self, device: SensorDevice) -> tuple[int, int, int]:
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

    def _check_force_sensor(self, device: SensorDevice) -> None:
        self._require_measuring_device(device)
        device.newtons_per_count = self._si_per_count(device, 1, CIA303_NEWTON, "newton")

    def _check_force_torque_sensor(self, device: SensorDevice) -> None:
        """CiA 404 with six channels: newton on 1-3, newton metre on 4-6; their resolutions."""
        self._require_measuring_device(device)
        channels = self._sdo_read(device, 0x6131, 0, "number of AI channels 0x6131:00")
        if channels < FORCE_TORQUE_CHANNELS:
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

    def _require_measuring_device(self, device: SensorDevice) -> None:
        device_type, profile, _ = self._read_profile(device)
        if profile != CIA404_MEASURING_DEVICE_PROFILE:
            raise self._error(
                device,
                f"device type 0x{device_type:08X} is profile CiA {profile}, not a CiA 404 "
                "measuring device (expected low 16 bits 0x0194)",
            )

    def _si_per_count(self, device: SensorDevice, channel: int, unit_code: int, unit: str) -> float:
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
            if not self._wait_for_state(index, HEARTBEAT_OPERATIONAL, wait_s):
                seen = [hex(state) for state in self._states_since_mark[index]]
                raise self._error(
                    device,
                    f"no heartbeat saying Operational (0x05) within {wait_s:.3g} s after NMT "
                    f"start (heartbeat states seen: {seen or 'none'})",
                )
        else:
            self._nmt_state[index] = UNKNOWN_STATE  # no heartbeat: the state is not monitored
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
        """Whether the node said `state` within `timeout_s` (or later, while the process that
        serves it works: `_patience`)."""
        deadline = time.monotonic() + timeout_s
        patience = self._patience
        if patience is not None:
            patience.begin()
        with self._heartbeat_seen:
            while state not in self._states_since_mark[index]:
                remaining = deadline - time.monotonic()
                if remaining <= 0.0:
                    extension_s = patience.extension_s() if patience is not None else 0.0
                    if extension_s <= 0.0:
                        return False
                    deadline = time.monotonic() + extension_s
                    continue
                self._heartbeat_seen.wait(remaining)
        return True

    def _sdo_variable(
        self, device: SensorDevice, index: int, subindex: int
    ) -> canopen.sdo.SdoVariable:
        variable = self._object_dictionary.get_variable(index, subindex)
        if variable is None:
            raise KeyError(f"0x{index:04X}:{subindex:02X} missing from sensor_object_dictionary()")
        return canopen.sdo.SdoVariable(device.node.sdo, variable)

    def _sdo_read(self, device: SensorDevice, index: int, subindex: int, what: str) -> int:
        variable = self._sdo_variable(device, index, subindex)
        return int(self._sdo_transfer(device, f"reading {what}", lambda: variable.raw))

    def _sdo_write(
        self, device: SensorDevice, index: int, subindex: int, value: int, what: str
    ) -> None:
        variable = self._sdo_variable(device, index, subindex)

        def write() -> None:
            variable.raw = value

        self._sdo_transfer(device, f"writing {what}", write)

    def _sdo_transfer(self, device: SensorDevice, action: str, transfer: Callable[[], T]) -> T:
        """One SDO transfer. An answer that did not come within `sdo_timeout_s` is asked for
        again while the process serving the node works (`_patience`, as the NMT waits): a
        loaded machine delays a lock-step emulator's answer past canopen's timeout, and the
        bring-up's expedited reads and writes are the same sent twice (a late answer to the
        first is the same answer; canopen drops one left in its queue before a request, and one
        that comes after is refused as another object's and asked for again)."""
        patience = self._patience
        if patience is not None:
            patience.begin()
        while True:
            try:
                return transfer()
            except canopen.SdoAbortedError as error:
                raise CanDeviceError(
                    f"{device.label} on {self.bus_description}: {action} refused: {error}"
                ) from None
            except canopen.SdoCommunicationError as error:
                if patience is not None and patience.extension_s() > 0.0:
                    continue
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
