"""SDO server (CiA 301 section 7.2.4): expedited and segmented upload and download.

Request (client -> server, COB-ID 0x600 + node) and response (0x580 + node) are 8-byte frames;
byte 0 is the command specifier, bytes 1-2 the index (little endian), byte 3 the sub-index:

    initiate download   ccs=1  001x nnes   -> 0x60 idx sub 0          (scs=3)
    download segment    ccs=0  000t nnnc   -> 001t 0000               (scs=1)
    initiate upload     ccs=2  0100 0000   -> 010x nnes idx sub data  (scs=2)
    upload segment      ccs=3  011t 0000   -> 000t nnnc data[7]       (scs=0)
    abort               ccs=4  1000 0000 idx sub code[4]  (either direction)

e = expedited (data in bytes 4-7), s = size indicated, n = number of bytes that hold no data,
t = toggle bit (starts at 0, alternates per segment), c = last segment. Block transfer
(ccs=5/6) is not implemented: it is answered with abort 0x05040001, and `canopen` uses it only
when asked to.
"""

from __future__ import annotations

import struct

from sim_backend.canbus.cia301 import SdoAbortCode
from sim_backend.canbus.object_store import ObjectStore, SdoAbort

_HEADER = struct.Struct("<BHB")
_ABORT = struct.Struct("<BHBL")
_U32 = struct.Struct("<L")

_CCS_DOWNLOAD_SEGMENT = 0
_CCS_INITIATE_DOWNLOAD = 1
_CCS_INITIATE_UPLOAD = 2
_CCS_UPLOAD_SEGMENT = 3
_CCS_ABORT = 4

_TOGGLE = 0x10


class SdoServer:
    """Answers SDO requests against an ObjectStore; one transfer at a time, like a real node."""

    def __init__(self, store: ObjectStore) -> None:
        self._store = store
        self._index = 0
        self._subindex = 0
        self._upload_data: bytes | None = None  # segmented upload in progress
        self._upload_position = 0
        self._download_buffer: bytearray | None = None  # segmented download in progress
        self._download_size: int | None = None
        self._toggle = 0

    def reset(self) -> None:
        """Forget any transfer in progress (NMT reset, power cycle)."""
        self._upload_data = None
        self._download_buffer = None
        self._download_size = None
        self._toggle = 0

    def handle_request(self, request: bytes | bytearray) -> bytes | None:
        """The 8-byte response to one request frame, or None when no response is due."""
        if len(request) < 1:
            return None
        request = bytes(request).ljust(8, b"\x00")
        command = request[0]
        ccs = command >> 5
        try:
            if ccs == _CCS_INITIATE_UPLOAD:
                return self._initiate_upload(request)
            if ccs == _CCS_UPLOAD_SEGMENT:
                return self._upload_segment(command)
            if ccs == _CCS_INITIATE_DOWNLOAD:
                return self._initiate_download(request)
            if ccs == _CCS_DOWNLOAD_SEGMENT:
                return self._download_segment(request)
            if ccs == _CCS_ABORT:
                self.reset()
                return None
            _, index, subindex = _HEADER.unpack_from(request)
            raise SdoAbort(SdoAbortCode.INVALID_COMMAND_SPECIFIER, index, subindex)
        except SdoAbort as abort:
            self.reset()
            return _ABORT.pack(0x80, abort.index, abort.subindex, int(abort.code))

    # --- upload (server -> client) ---------------------------------------------------------
    def _initiate_upload(self, request: bytes) -> bytes:
        self.reset()
        _, index, subindex = _HEADER.unpack_from(request)
        data = self._store.sdo_read(index, subindex)
        if 1 <= len(data) <= 4:
            command = 0x43 | ((4 - len(data)) << 2)  # expedited, size indicated
            return _HEADER.pack(command, index, subindex) + data.ljust(4, b"\x00")
        self._index, self._subindex = index, subindex
        self._upload_data = data
        self._upload_position = 0
        return _HEADER.pack(0x41, index, subindex) + _U32.pack(len(data))

    def _upload_segment(self, command: int) -> bytes:
        if self._upload_data is None:
            raise SdoAbort(SdoAbortCode.INVALID_COMMAND_SPECIFIER, self._index, self._subindex)
        toggle = command & _TOGGLE
        if toggle != self._toggle:
            raise SdoAbort(SdoAbortCode.TOGGLE_NOT_ALTERNATED, self._index, self._subindex)
        chunk = self._upload_data[self._upload_position : self._upload_position + 7]
        self._upload_position += len(chunk)
        last = self._upload_position >= len(self._upload_data)
        response = bytes([toggle | ((7 - len(chunk)) << 1) | int(last)]) + chunk.ljust(7, b"\x00")
        self._toggle ^= _TOGGLE
        if last:
            self.reset()
        return response

    # --- download (client -> server) -------------------------------------------------------
    def _initiate_download(self, request: bytes) -> bytes:
        self.reset()
        command, index, subindex = _HEADER.unpack_from(request)
        expedited = bool(command & 0x02)
        size_indicated = bool(command & 0x01)
        if expedited:
            if size_indicated:
                data = request[4 : 8 - ((command >> 2) & 0x3)]
            else:  # size unspecified: as many bytes as the object's data type holds
                variable = self._store.lookup(index, subindex)
                data = request[4 : 4 + min(4, max(1, len(variable) // 8))]
            self._store.sdo_write(index, subindex, data)
            return _HEADER.pack(0x60, index, subindex) + b"\x00" * 4
        self._index, self._subindex = index, subindex
        self._download_buffer = bytearray()
        self._download_size = _U32.unpack_from(request, 4)[0] if size_indicated else None
        return _HEADER.pack(0x60, index, subindex) + b"\x00" * 4

    def _download_segment(self, request: bytes) -> bytes:
        if self._download_buffer is None:
            raise SdoAbort(SdoAbortCode.INVALID_COMMAND_SPECIFIER, self._index, self._subindex)
        command = request[0]
        toggle = command & _TOGGLE
        if toggle != self._toggle:
            raise SdoAbort(SdoAbortCode.TOGGLE_NOT_ALTERNATED, self._index, self._subindex)
        length = 7 - ((command >> 1) & 0x7)
        self._download_buffer += request[1 : 1 + length]
        self._toggle ^= _TOGGLE
        if command & 0x01:  # last segment: the write takes effect now
            data = bytes(self._download_buffer)
            index, subindex, size = self._index, self._subindex, self._download_size
            self.reset()
            if size is not None and size != len(data):
                raise SdoAbort(SdoAbortCode.LENGTH_MISMATCH, index, subindex)
            self._store.sdo_write(index, subindex, data)
        return bytes([0x20 | toggle]) + b"\x00" * 7
