"""TPDO1 of an emulated CAN sensor node: its static mapping read from the EDS, its frame on
SYNC or on the event timer, and its communication parameters (0x1800) cached from the object
store with the checks of writes to them.

CiA 301: TPDO1 (COB-ID in 0x1800:01, bit 31 = invalid) is sent only in Operational.
Transmission type (0x1800:02): 0 = on SYNC when the value changed, 1..240 = every n-th SYNC,
254/255 = every 0x1800:05 ms (event timer). Types 241..253 are refused (abort 0x06090030). The
COB-ID is an 11-bit identifier and changes only while bit 31 is set.
"""

from __future__ import annotations

import struct
from typing import Any

import can
from canopen.objectdictionary import datatypes

from sim_backend.canbus.cia301 import (
    PDO_COB_ID_EXTENDED,
    PDO_COB_ID_INVALID,
    STANDARD_ID_MASK,
    TRANSMISSION_ACYCLIC_SYNC,
    TRANSMISSION_EVENT_MANUFACTURER,
    TRANSMISSION_EVENT_PROFILE,
    TRANSMISSION_SYNC_MAX,
    SdoAbortCode,
)

TPDO_COMMUNICATION = 0x1800
_TPDO_MAPPING = 0x1A00

# PDO-mappable integer types and their struct codes (little endian, CiA 301 byte order).
_STRUCT_CODES = {
    datatypes.INTEGER8: "b",
    datatypes.INTEGER16: "h",
    datatypes.INTEGER32: "i",
    datatypes.UNSIGNED8: "B",
    datatypes.UNSIGNED16: "H",
    datatypes.UNSIGNED32: "I",
}


class TpdoProducer:
    """The TPDO of `CanopenSlave` (sim_backend/canbus/slave.py), a mixin: it works on the
    node's object store, NMT state and clock."""

    def _static_tpdo_mapping(self) -> tuple[list[tuple[int, int]], struct.Struct]:
        count = int(self._store.stored_value(_TPDO_MAPPING, 0))
        objects: list[tuple[int, int]] = []
        codes = "<"
        for entry in range(1, count + 1):
            mapped = int(self._store.stored_value(_TPDO_MAPPING, entry))
            index, subindex, bits = mapped >> 16, (mapped >> 8) & 0xFF, mapped & 0xFF
            variable = self._store.variable(index, subindex)
            code = _STRUCT_CODES.get(variable.data_type)
            if code is None or not variable.pdo_mappable or len(variable) != bits:
                raise ValueError(
                    f"EDS maps 0x{mapped:08X} into TPDO1, which is not a PDO-mappable "
                    f"{bits}-bit integer object"
                )
            objects.append((index, subindex))
            codes += code
        tpdo_struct = struct.Struct(codes)
        if tpdo_struct.size > 8:
            raise ValueError(f"TPDO1 mapping of the EDS needs {tpdo_struct.size} bytes (max 8)")
        return objects, tpdo_struct

    def _tpdo_values(self) -> tuple[Any, ...]:
        readers = self._tpdo_readers
        if readers is None:  # (the read hooks are all registered once the node is built)
            readers = self._tpdo_readers = [self._store.reader(*key) for key in self._tpdo_objects]
        if len(readers) == 1:
            return (readers[0](),)
        return tuple([read() for read in readers])

    def _tpdo_frame(self, values: tuple[Any, ...]) -> can.Message:
        self._last_transmitted = values
        return self._frame(self._tpdo_cob_id, self._tpdo_struct.pack(*values))

    def _on_sync(self) -> list[can.Message]:
        if not self._tpdo_enabled:
            return []
        transmission_type = self._transmission_type
        if transmission_type == 1:  # every SYNC (the count stays 0): the usual, kept short
            values = self._tpdo_values()
            self._last_transmitted = values
            return [self._frame(self._tpdo_cob_id, self._tpdo_struct.pack(*values))]
        if transmission_type == TRANSMISSION_ACYCLIC_SYNC:
            values = self._tpdo_values()
            return [] if values == self._last_transmitted else [self._tpdo_frame(values)]
        if transmission_type <= TRANSMISSION_SYNC_MAX:
            self._sync_count += 1
            if self._sync_count < transmission_type:
                return []
            self._sync_count = 0
            return [self._tpdo_frame(self._tpdo_values())]
        return []  # event-driven types ignore SYNC

    def _refresh_tpdo_cache(self) -> None:
        cob_id = int(self._store.stored_value(TPDO_COMMUNICATION, 1))
        self._tpdo_cob_id = cob_id & STANDARD_ID_MASK
        self._tpdo_enabled = not cob_id & PDO_COB_ID_INVALID
        self._transmission_type = int(self._store.stored_value(TPDO_COMMUNICATION, 2))

    def _validate_tpdo_cob_id(self, value: int) -> SdoAbortCode | None:
        if value & PDO_COB_ID_EXTENDED or not 0x001 <= value & STANDARD_ID_MASK <= 0x7FF:
            return SdoAbortCode.VALUE_RANGE_EXCEEDED  # only 11-bit identifiers
        old = int(self._store.stored_value(TPDO_COMMUNICATION, 1))
        both_valid = not (old | value) & PDO_COB_ID_INVALID
        if both_valid and (old & STANDARD_ID_MASK) != (value & STANDARD_ID_MASK):
            return SdoAbortCode.VALUE_RANGE_EXCEEDED  # CiA 301: set bit 31 before changing it
        return None


def transmission_type_refusal(value: int) -> SdoAbortCode | None:
    supported = value <= TRANSMISSION_SYNC_MAX or value in (
        TRANSMISSION_EVENT_MANUFACTURER,
        TRANSMISSION_EVENT_PROFILE,
    )
    return None if supported and value >= 0 else SdoAbortCode.VALUE_RANGE_EXCEEDED
