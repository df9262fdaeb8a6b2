"""Emulated six-axis foot force/torque sensor: a CiA 404 node with six channels on CAN.

DYROS-JET carries a force/torque sensor under each ankle; their model and bus interface are not
published. ASSUMPTION (a documented choice, not a fact about the robot): each is emulated as a
CiA 404 measuring device with six analogue inputs, object dictionary
`sim_backend/data/emulated_cia404_ft_sensor.eds`:

    0x1000      device type          0x00020194 (CiA 404, analogue input block)
    0x6131:1..6 AI physical unit PV  0x00210000 newton (Fx, Fy, Fz); 0x00230000 (N m: CiA
                                     303-2 has no code of its own for the newton metre, the
                                     joule has its dimension) for Mx, My, Mz
    0x6132:1..6 AI decimal digits PV 1 (forces: 0.1 N per count), 2 (moments: 0.01 N m)
    0x7130:1..6 AI input PV          INTEGER16, PDO-mappable
    TPDO1 (0x180 + id)  0x7130:1, :2, :3   (Fx, Fy, Fz; 6 bytes, little endian)
    TPDO2 (0x280 + id)  0x7130:4, :5, :6   (Mx, My, Mz)

so PV = round(value / 10**prefix * 10**decimal_digits), clipped to the INTEGER16 range
(+-3276.7 N, +-327.67 N m; a saturated sensor reads its limit, as a real one does).

All six channels are latched together when SYNC arrives (one sample feeds both TPDOs, as a
sensor that converts its channels simultaneously). TPDO1 follows the CiA 301 machinery of
`CanopenSlave` (transmission types 0..240, 254/255 with its event timer); TPDO2 supports the
SYNC types 0..240 (others are refused with abort 0x06090030) and is sent right after TPDO1.

What the values mean: the ground's force and moment ON THE ROBOT through this foot, in the
sensor's frame, the moment about the sensor's origin (the emulated DYROS-JET puts the sensor at
the ankle axis, in the *_AnkleRoll_Link frame). Faults: "dead" and NMT as for every node;
"stale" freezes all six channels at the last sample; "noisy" adds `noise_counts_rms` counts of
Gaussian noise to each channel.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from typing import Any

import can
import numpy as np

from sim_backend.canbus.cia301 import (
    PDO_COB_ID_INVALID,
    STANDARD_ID_MASK,
    TRANSMISSION_ACYCLIC_SYNC,
    TRANSMISSION_SYNC_MAX,
    SdoAbortCode,
)
from sim_backend.canbus.object_store import eds_path
from sim_backend.canbus.slave import DEFAULT_BOOTUP_DELAY_S, CanopenSlave

FT_SENSOR_EDS_FILE = "emulated_cia404_ft_sensor.eds"

_PHYSICAL_UNIT = 0x6131
_DECIMAL_DIGITS = 0x6132
_PROCESS_VALUE = 0x7130
_TPDO2_COMMUNICATION = 0x1801
_TPDO2_MAPPING = 0x1A01
_N_CHANNELS = 6
_INT16_MIN, _INT16_MAX = -32768, 32767

WrenchSource = Callable[[], tuple[np.ndarray, np.ndarray]]


class ForceTorqueSensorNode(CanopenSlave):
    """A six-channel CiA 404 force/torque node; see the module docstring.

    wrench_source: returns (force [N], moment [N m]) in the sensor frame at the instant it is
    called; called once per SYNC the node answers (and per SDO read of a 0x7130 channel).
    """

    def __init__(
        self,
        node_id: int,
        wrench_source: WrenchSource,
        *,
        heartbeat_ms: int = 100,
        seed: int = 0,
        tpdo_transmission_type: int = 1,
        bootup_delay_s: float = DEFAULT_BOOTUP_DELAY_S,
    ) -> None:
        if not callable(wrench_source):
            raise TypeError("wrench_source must be a callable returning (force_n, torque_nm)")
        self._wrench_source = wrench_source
        self._counts_per_unit = np.ones(_N_CHANNELS)
        self._latched = [0] * _N_CHANNELS
        self._latched_valid = False
        self._in_sync = False  # TPDO reads use the SYNC's latched sample, SDO reads sample anew
        self._tpdo2_count = 0
        self._tpdo2_last: tuple[Any, ...] | None = None
        super().__init__(
            node_id,
            eds_path(FT_SENSOR_EDS_FILE),
            process_value_object=(_PROCESS_VALUE, 1),
            heartbeat_ms=heartbeat_ms,
            seed=seed,
            tpdo_transmission_type=tpdo_transmission_type,
            serial_number=0x4046_0000 + node_id,
            bootup_delay_s=bootup_delay_s,
        )
        for channel in range(1, _N_CHANNELS + 1):
            unit = int(self._store.stored_value(_PHYSICAL_UNIT, channel))
            prefix_exponent = int.from_bytes(bytes([unit >> 24]), "little", signed=True)
            digits = int(self._store.stored_value(_DECIMAL_DIGITS, channel))
            self._counts_per_unit[channel - 1] = 10.0 ** (digits - prefix_exponent)
            self._store.on_read(_PROCESS_VALUE, channel, self._channel_hook(channel - 1))
        self._scales = self._counts_per_unit.tolist()
        self._store.validate_writes(_TPDO2_COMMUNICATION, 2, _sync_types_only)
        self._tpdo2_objects, self._tpdo2_struct = self._tpdo2_mapping()
        self._tpdo2_channels = [sub - 1 for _, sub in self._tpdo2_objects]

    # --- process values ------------------------------------------------------------------------
    def _ideal_raw(self) -> float:
        """Channel 1 (Fx) in counts (the base class's single-value path: stale entry)."""
        force, _ = self._wrench_source()
        return float(force[0]) * float(self._counts_per_unit[0])

    def _sample_all(self) -> None:
        """Latch the six channels now (the SYNC instant), with the node's fault applied."""
        mode = self.fault.mode
        if mode == "stale" and self._latched_valid:
            return
        force, torque = self._wrench_source()
        values = np.concatenate((force, torque)).tolist()
        if len(values) != _N_CHANNELS or not all(map(math.isfinite, values)):
            raise ValueError(f"node {self.node_id}: the wrench source gave {values!r}")
        # Python numbers, channel by channel (the same products and sums as on arrays)
        counts = [value * scale for value, scale in zip(values, self._scales, strict=True)]
        if mode == "noisy" and self.fault.noise_counts_rms > 0.0:
            rms = self.fault.noise_counts_rms
            noise = self._normals.take(_N_CHANNELS).tolist()
            counts = [count + z * rms for count, z in zip(counts, noise, strict=True)]
        self._latched = [
            max(_INT16_MIN, min(_INT16_MAX, math.floor(value + 0.5))) for value in counts
        ]
        self._latched_valid = True

    def sample_wrench(self, now_s: float) -> tuple[np.ndarray, np.ndarray] | None:
        """(force [N], moment [N m]) a SYNC at `now_s` would latch, in the units its objects
        define (None while the node is dead): the in-process counterpart of its TPDOs."""
        self._prologue(now_s)
        if self.fault.mode == "dead":
            return None
        self._sample_all()
        values = np.asarray(self._latched, dtype=float) / self._counts_per_unit
        return values[:3], values[3:]

    def _channel_hook(self, channel: int) -> Callable[[], int]:
        def read() -> int:
            if not self._in_sync:
                self._sample_all()  # an SDO read samples now
            return self._latched[channel]

        return read

    # --- SYNC: TPDO1 (base class) then TPDO2 ----------------------------------------------------
    def _on_sync(self) -> list[can.Message]:
        self._sample_all()
        self._in_sync = True
        try:
            frames = super()._on_sync()
            frames.extend(self._tpdo2_on_sync())
        finally:
            self._in_sync = False
        return frames

    def _tpdo2_on_sync(self) -> list[can.Message]:
        cob_id = int(self._store.stored_value(_TPDO2_COMMUNICATION, 1))
        if cob_id & PDO_COB_ID_INVALID:
            return []
        transmission_type = int(self._store.stored_value(_TPDO2_COMMUNICATION, 2))
        latched = self._latched  # (in a SYNC the channels read the latched sample)
        values = tuple([latched[channel] for channel in self._tpdo2_channels])
        if transmission_type == TRANSMISSION_ACYCLIC_SYNC:
            if values == self._tpdo2_last:
                return []
        elif transmission_type <= TRANSMISSION_SYNC_MAX:
            self._tpdo2_count += 1
            if self._tpdo2_count < transmission_type:
                return []
            self._tpdo2_count = 0
        else:
            return []
        self._tpdo2_last = values
        return [self._frame(cob_id & STANDARD_ID_MASK, self._tpdo2_struct.pack(*values))]

    def _tpdo2_mapping(self) -> tuple[list[tuple[int, int]], struct.Struct]:
        count = int(self._store.stored_value(_TPDO2_MAPPING, 0))
        objects = []
        for entry in range(1, count + 1):
            mapped = int(self._store.stored_value(_TPDO2_MAPPING, entry))
            objects.append((mapped >> 16, (mapped >> 8) & 0xFF))
            if mapped & 0xFF != 16 or mapped >> 16 != _PROCESS_VALUE:
                raise ValueError(f"TPDO2 must map 16-bit AI input PVs, the EDS has 0x{mapped:08X}")
        return objects, struct.Struct("<" + "h" * count)

    # --- hooks of the base class ----------------------------------------------------------------
    def _reset_application(self) -> None:
        self._latched = [0] * _N_CHANNELS
        self._latched_valid = False
        self._tpdo2_count = 0
        self._tpdo2_last = None

    def _refresh_tpdo_cache(self) -> None:
        super()._refresh_tpdo_cache()
        self._tpdo2_count = 0
        self._tpdo2_last = None

    def _on_object_written(self, index: int, subindex: int, value: Any) -> None:
        if index == _TPDO2_COMMUNICATION:
            self._tpdo2_count = 0
            self._tpdo2_last = None


def _sync_types_only(value: int) -> SdoAbortCode | None:
    return None if 0 <= value <= TRANSMISSION_SYNC_MAX else SdoAbortCode.VALUE_RANGE_EXCEEDED
