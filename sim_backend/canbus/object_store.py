"""The value store behind an emulated node's object dictionary, with SDO access rules.

The object *definitions* (index, sub-index, data type, access, limits, defaults) come from the
device's EDS file, parsed by `canopen.import_od`; this module keeps the *values* and applies
the CiA 301 access rules an SDO server must enforce (object/sub-index exists, read-only,
length matches the data type, value within LowLimit/HighLimit), answering violations with the
CiA 301 abort code. Device-specific behaviour hangs on hooks: a read hook computes a live value
(e.g. the position at this instant), a write validator refuses a value the device does not
accept, and `after_write` lets the device react to a stored write (restart a timer, ...).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from importlib import resources
from pathlib import Path
from typing import Any

import canopen
from canopen.objectdictionary import ODArray, ODRecord, ODVariable

from sim_backend.canbus.cia301 import SdoAbortCode

ReadHook = Callable[[], Any]
WriteValidator = Callable[[Any], SdoAbortCode | None]  # an abort code refuses the write


def eds_path(file_name: str) -> Path:
    """Path of an EDS file shipped in `sim_backend/data/`.

    Located from this module's package (sim_backend.canbus), not from the top-level name: a
    folder `tests/sim_backend/` on sys.path makes `sim_backend` resolve to a namespace package
    there when the product is installed in editable mode, and resources.files("sim_backend")
    would then look in the tests."""
    path = Path(str(resources.files("sim_backend.canbus"))).parent / "data" / file_name
    if not path.is_file():
        raise FileNotFoundError(f"EDS file {file_name!r} not found in {path.parent}")
    return path


class SdoAbort(Exception):
    """An SDO request the server refuses; `code` is the CiA 301 abort code it sends."""

    def __init__(self, code: SdoAbortCode, index: int, subindex: int) -> None:
        super().__init__(
            f"SDO abort 0x{int(code):08X} ({code.name}) on 0x{index:04X}:{subindex:02X}"
        )
        self.code = code
        self.index = index
        self.subindex = subindex


class ObjectStore:
    """Values of every object in an object dictionary, keyed by (index, sub-index)."""

    def __init__(self, eds_file: Path, node_id: int) -> None:
        od = canopen.import_od(str(eds_file), node_id)
        self._variables: dict[tuple[int, int], ODVariable] = {}
        self._indices: set[int] = set()
        for obj in od.values():
            self._indices.add(obj.index)
            members: Iterable[ODVariable]
            members = obj.subindices.values() if isinstance(obj, ODRecord | ODArray) else (obj,)
            for variable in members:
                self._variables[(variable.index, variable.subindex)] = variable
        self._defaults: dict[tuple[int, int], Any] = {
            key: (variable.default if variable.default is not None else 0)
            for key, variable in self._variables.items()
        }
        self._values: dict[tuple[int, int], Any] = dict(self._defaults)
        self._read_hooks: dict[tuple[int, int], ReadHook] = {}
        self._validators: dict[tuple[int, int], WriteValidator] = {}
        self.after_write: Callable[[int, int, Any], None] | None = None

    # --- configuration by the device model -------------------------------------------------
    def variable(self, index: int, subindex: int = 0) -> ODVariable:
        """The definition of one entry (KeyError with a clear message if it is not defined)."""
        try:
            return self._variables[(index, subindex)]
        except KeyError:
            raise KeyError(f"object 0x{index:04X}:{subindex:02X} is not in the EDS") from None

    def set_default(self, index: int, subindex: int, value: Any) -> None:
        """Change the power-on default of an entry (a device's factory setting) and its value."""
        self.variable(index, subindex)
        self._defaults[(index, subindex)] = value
        self._values[(index, subindex)] = value

    def on_read(self, index: int, subindex: int, hook: ReadHook) -> None:
        self.variable(index, subindex)
        self._read_hooks[(index, subindex)] = hook

    def validate_writes(self, index: int, subindex: int, validator: WriteValidator) -> None:
        self.variable(index, subindex)
        self._validators[(index, subindex)] = validator

    # --- internal access (no SDO rules) ----------------------------------------------------
    def value(self, index: int, subindex: int = 0) -> Any:
        key = (index, subindex)
        hook = self._read_hooks.get(key)
        return hook() if hook is not None else self._values[key]

    def reader(self, index: int, subindex: int = 0) -> Callable[[], Any]:
        """A function that returns `value(index, subindex)` (its read hook itself, if any)."""
        key = (index, subindex)
        self.variable(index, subindex)
        hook = self._read_hooks.get(key)
        if hook is not None:
            return hook
        values = self._values
        return lambda: values[key]

    def stored_value(self, index: int, subindex: int = 0) -> Any:
        """The stored value, ignoring read hooks."""
        return self._values[(index, subindex)]

    def reset(self, indices: range | None = None) -> None:
        """Restore the defaults of every entry (or of the entries whose index is in `indices`)."""
        for key, default in self._defaults.items():
            if indices is None or key[0] in indices:
                self._values[key] = default

    # --- SDO access ------------------------------------------------------------------------
    def lookup(self, index: int, subindex: int) -> ODVariable:
        """The definition an SDO request addresses; raises SdoAbort if there is none."""
        variable = self._variables.get((index, subindex))
        if variable is None:
            code = (
                SdoAbortCode.SUBINDEX_DOES_NOT_EXIST
                if index in self._indices
                else SdoAbortCode.OBJECT_DOES_NOT_EXIST
            )
            raise SdoAbort(code, index, subindex)
        return variable

    def sdo_read(self, index: int, subindex: int) -> bytes:
        """Encoded value for an SDO upload; raises SdoAbort."""
        variable = self.lookup(index, subindex)
        if variable.access_type == "wo":
            raise SdoAbort(SdoAbortCode.READ_WRITE_ONLY, index, subindex)
        return variable.encode_raw(self.value(index, subindex))

    def sdo_write(self, index: int, subindex: int, data: bytes) -> None:
        """Apply an SDO download; raises SdoAbort."""
        variable = self.lookup(index, subindex)
        if "w" not in variable.access_type:
            raise SdoAbort(SdoAbortCode.WRITE_READ_ONLY, index, subindex)
        if variable.fixed_size:
            expected_bytes = len(variable) // 8
            if len(data) > expected_bytes:
                raise SdoAbort(SdoAbortCode.LENGTH_TOO_HIGH, index, subindex)
            if len(data) < expected_bytes:
                raise SdoAbort(SdoAbortCode.LENGTH_TOO_LOW, index, subindex)
        value = variable.decode_raw(bytes(data))
        if variable.min is not None and value < variable.min:
            raise SdoAbort(SdoAbortCode.VALUE_TOO_LOW, index, subindex)
        if variable.max is not None and value > variable.max:
            raise SdoAbort(SdoAbortCode.VALUE_TOO_HIGH, index, subindex)
        validator = self._validators.get((index, subindex))
        if validator is not None:
            refusal = validator(value)
            if refusal is not None:
                raise SdoAbort(refusal, index, subindex)
        self._values[(index, subindex)] = value
        if self.after_write is not None:
            self.after_write(index, subindex, value)
