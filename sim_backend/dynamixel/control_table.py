"""The control table of the Dynamixel Pro H54-200-S500-R (model 54024) as data.

Source: ROBOTIS e-Manual, H54-200-S500-R, "Control Table of EEPROM Area" and "Control Table of
RAM Area" (https://emanual.robotis.com/docs/en/dxl/pro/h54-200-s500-r/, repository
ROBOTIS-GIT/emanual, docs/en/dxl/pro/h54-200-s500-r.md) plus the item includes it pulls in
(_includes/en/dxl/control_table_*_pro.md). The same addresses appear in ROBOTIS'
dynamixel-workbench (items_EXTPRO) and ROBOTIS-Framework (H54-200-S500-R.device).

Do not confuse with the H54-200-S500-R(A) (model 54025), whose table is different.

Choices where the e-Manual is silent or inconsistent (the emulator's, documented here):
- Undefined bytes (10, 12, 566..585, 590..593, 619..620) read as 0; a write touching one is an
  Access Error. ROBOTIS-Framework lists a "drive_mode" at 10; the e-Manual does not, so neither
  do we.
- Baud Rate range 0..8 (the index table of the include; the main table's "0 ~ 13" has no
  meaning for indices 9..13).
- Return Delay Time range 0..254 (the include; the main table says 0 ~ 255).
- Torque Limit range 0..1860 (the H54 table; the generic PRO include says 0..32,767).
- Indirect Address range 562..892 (the include: "limited to RAM area (Address 562 ~ 892)"; the
  main table's "562 ~ 949" runs past the end of the table).
- Initial values the e-Manual prints as "-": Model Information 0, Acceleration Limit 255,
  Goal Position = Present Position at power-on and reboot, Present Input Voltage 240 (24.0 V),
  Present Temperature 30 degC, the other Present* items 0. Firmware Version comes from the
  device's constructor.
- External Port Mode initial value 0 (the H54 table; the include marks 3 as default).
- External Port Data is writable only while its port is in mode 1 (digital output), read-only
  otherwise (the include's access column).
- Goal Acceleration must lie in 0..Acceleration Limit (Data Limit Error otherwise).
- Goal Position is checked against Min/Max Position Limit except in Extended Position Control
  Mode (4), where the include says the limits are ignored.
"""

from __future__ import annotations

import enum
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

MODEL_NUMBER_H54_200_S500_R = 54024  # 0xD308, e-Manual "Model Number(0)"
TABLE_SIZE_BYTES = 893  # addresses 0..892; Hardware Error Status is the last item

INT32_MIN = -(2**31)
INT32_MAX = 2**31 - 1

# Baud Rate(8) index -> bits per second (e-Manual include control_table_8_baudrate_pro.md).
BAUD_RATE_BPS: Mapping[int, int] = {
    0: 9_600,
    1: 57_600,
    2: 115_200,
    3: 1_000_000,
    4: 2_000_000,
    5: 3_000_000,
    6: 4_000_000,
    7: 4_500_000,
    8: 10_500_000,
}
FACTORY_BAUD_INDEX = 1  # 57,600 bps

RETURN_DELAY_UNIT_S = 2e-6  # Return Delay Time(9): 2 us per unit

# Hardware Error Status(892) / Shutdown(48) bits (e-Manual include control_table_shutdown.md).
HARDWARE_ERROR_BITS_MASK = 0x3F  # bits 7 and 6 are "not used, always 0"

INDIRECT_COUNT = 256
INDIRECT_ADDRESS_BASE = 49  # Indirect Address n at 49 + 2(n - 1)
INDIRECT_DATA_BASE = 634  # Indirect Data n at 634 + (n - 1)
INDIRECT_TARGET_MIN = 562
INDIRECT_TARGET_MAX = 892


class Access(enum.Enum):
    READ = "R"
    READ_WRITE = "RW"


class Area(enum.Enum):
    EEPROM = "EEPROM"  # writable only while Torque Enable = 0; kept across REBOOT
    RAM = "RAM"  # back to initial values on REBOOT


@dataclass(frozen=True)
class ControlItem:
    """One control-table item.

    `minimum`/`maximum`: the valid range (outside it: Data Range Error). `allowed_values`, when
    set, narrows it further. `limit_low`/`limit_high`: the bound set by another item (outside
    it: Data Limit Error): an item name, "-" + an item name for its negative, or a constant.
    `writable_when`: (item name, value) that must hold for a write to be allowed.
    `measured`: owned by the firmware (sensor values): kept across a REBOOT.
    """

    name: str
    address: int
    size: int
    access: Access
    area: Area
    default: int
    minimum: int
    maximum: int
    signed: bool = False
    allowed_values: frozenset[int] | None = None
    limit_low: str | int | None = None
    limit_high: str | None = None
    writable_when: tuple[str, int] | None = None
    measured: bool = False

    @property
    def end(self) -> int:
        """One past the last address."""
        return self.address + self.size

    def encode(self, value: int) -> bytes:
        """Little-endian bytes of `value` (two's complement when signed); ValueError if it
        does not fit the item's size."""
        try:
            return int(value).to_bytes(self.size, "little", signed=self.signed)
        except OverflowError:
            kind = "signed" if self.signed else "unsigned"
            raise ValueError(
                f"{value} does not fit {self.name!r} ({self.size}-byte {kind})"
            ) from None

    def decode(self, raw: bytes | bytearray) -> int:
        return int.from_bytes(raw, "little", signed=self.signed)

    def in_range(self, value: int) -> bool:
        if not self.minimum <= value <= self.maximum:
            return False
        return self.allowed_values is None or value in self.allowed_values


def _eeprom(
    name: str, address: int, size: int, default: int, lo: int, hi: int, **kw
) -> ControlItem:
    access = kw.pop("access", Access.READ_WRITE)
    return ControlItem(name, address, size, access, Area.EEPROM, default, lo, hi, **kw)


def _ram(name: str, address: int, size: int, default: int, lo: int, hi: int, **kw) -> ControlItem:
    access = kw.pop("access", Access.READ_WRITE)
    return ControlItem(name, address, size, access, Area.RAM, default, lo, hi, **kw)


def _read_only(
    area: Area,
    name: str,
    address: int,
    size: int,
    default: int,
    signed: bool = False,
    measured: bool = False,
) -> ControlItem:
    lo = -(2 ** (8 * size - 1)) if signed else 0
    hi = 2 ** (8 * size - 1) - 1 if signed else 2 ** (8 * size) - 1
    return ControlItem(
        name, address, size, Access.READ, area, default, lo, hi, signed=signed, measured=measured
    )


def _h54_items() -> tuple[ControlItem, ...]:
    """The H54's control table, address order: EEPROM (0..560), then RAM (562..892)."""
    return (*_h54_eeprom_items(), *_h54_ram_items())


def _h54_eeprom_items() -> list[ControlItem]:
    eeprom = Area.EEPROM
    items = [
        _read_only(eeprom, "Model Number", 0, 2, MODEL_NUMBER_H54_200_S500_R),
        _read_only(eeprom, "Model Information", 2, 4, 0),
        _read_only(eeprom, "Firmware Version", 6, 1, 0),
        _eeprom("ID", 7, 1, 1, 0, 252),
        _eeprom("Baud Rate", 8, 1, FACTORY_BAUD_INDEX, 0, 8),
        _eeprom("Return Delay Time", 9, 1, 250, 0, 254),
        _eeprom("Operating Mode", 11, 1, 3, 0, 4, allowed_values=frozenset({0, 1, 3, 4})),
        _eeprom("Homing Offset", 13, 4, 0, INT32_MIN, INT32_MAX, signed=True),
        _eeprom("Moving Threshold", 17, 4, 50, 0, INT32_MAX),
        _eeprom("Temperature Limit", 21, 1, 80, 0, 100),
        _eeprom("Max Voltage Limit", 22, 2, 400, 0, 400),
        _eeprom("Min Voltage Limit", 24, 2, 150, 0, 400),
        _eeprom("Acceleration Limit", 26, 4, 255, 0, INT32_MAX),
        _eeprom("Torque Limit", 30, 2, 620, 0, 1860),
        _eeprom("Velocity Limit", 32, 4, 17_000, 0, INT32_MAX),
        _eeprom("Max Position Limit", 36, 4, 250_961, INT32_MIN, INT32_MAX, signed=True),
        _eeprom("Min Position Limit", 40, 4, -250_961, INT32_MIN, INT32_MAX, signed=True),
    ]
    items += [_eeprom(f"External Port Mode {k}", 43 + k, 1, 0, 0, 3) for k in range(1, 5)]
    items.append(_eeprom("Shutdown", 48, 1, 58, 0, 255))
    items += [
        _eeprom(
            f"Indirect Address {n}",
            INDIRECT_ADDRESS_BASE + 2 * (n - 1),
            2,
            INDIRECT_DATA_BASE + (n - 1),
            INDIRECT_TARGET_MIN,
            INDIRECT_TARGET_MAX,
        )
        for n in range(1, INDIRECT_COUNT + 1)
    ]
    return items


def _h54_ram_items() -> list[ControlItem]:
    ram = Area.RAM
    items = [
        _ram("Torque Enable", 562, 1, 0, 0, 1),
        _ram("LED Red", 563, 1, 0, 0, 255),
        _ram("LED Green", 564, 1, 0, 0, 255),
        _ram("LED Blue", 565, 1, 0, 0, 255),
        _ram("Velocity I Gain", 586, 2, 14, 0, 65_535),
        _ram("Velocity P Gain", 588, 2, 399, 0, 65_535),
        _ram("Position P Gain", 594, 2, 32, 0, 65_535),
        _ram(
            "Goal Position",
            596,
            4,
            0,
            INT32_MIN,
            INT32_MAX,
            signed=True,
            limit_low="Min Position Limit",
            limit_high="Max Position Limit",
        ),
        _ram(
            "Goal Velocity",
            600,
            4,
            0,
            INT32_MIN,
            INT32_MAX,
            signed=True,
            limit_low="-Velocity Limit",
            limit_high="Velocity Limit",
        ),
        _ram(
            "Goal Torque",
            604,
            2,
            0,
            -32_768,
            32_767,
            signed=True,
            limit_low="-Torque Limit",
            limit_high="Torque Limit",
        ),
        _ram(
            "Goal Acceleration",
            606,
            4,
            0,
            -INT32_MAX,
            INT32_MAX,
            signed=True,
            limit_low=0,
            limit_high="Acceleration Limit",
        ),
        _read_only(ram, "Moving", 610, 1, 0, measured=True),
        _read_only(ram, "Present Position", 611, 4, 0, signed=True, measured=True),
        _read_only(ram, "Present Velocity", 615, 4, 0, signed=True, measured=True),
        _read_only(ram, "Present Current", 621, 2, 0, signed=True, measured=True),
        _read_only(ram, "Present Input Voltage", 623, 2, 240, measured=True),
        _read_only(ram, "Present Temperature", 625, 1, 30, measured=True),
    ]
    items += [
        _ram(
            f"External Port Data {k}",
            624 + 2 * k,
            2,
            0,
            0,
            4095,
            writable_when=(f"External Port Mode {k}", 1),
        )
        for k in range(1, 5)
    ]
    items += [
        _ram(f"Indirect Data {n}", INDIRECT_DATA_BASE + (n - 1), 1, 0, 0, 255)
        for n in range(1, INDIRECT_COUNT + 1)
    ]
    items += [
        _read_only(ram, "Registered Instruction", 890, 1, 0),
        _ram("Status Return Level", 891, 1, 2, 0, 2),
        _read_only(ram, "Hardware Error Status", 892, 1, 0),
    ]
    return items


class ControlTableLayout:
    """Lookup of items by name and by byte address; validates that items do not overlap."""

    def __init__(self, items: Iterable[ControlItem], size_bytes: int) -> None:
        self.items: tuple[ControlItem, ...] = tuple(items)
        self.size_bytes = size_bytes
        self._by_name: dict[str, ControlItem] = {}
        self._at: list[ControlItem | None] = [None] * size_bytes
        for item in self.items:
            if item.name in self._by_name:
                raise ValueError(f"duplicate control-table item name {item.name!r}")
            if item.address < 0 or item.end > size_bytes:
                raise ValueError(f"{item.name!r} at {item.address} runs past the table end")
            for address in range(item.address, item.end):
                if self._at[address] is not None:
                    raise ValueError(
                        f"{item.name!r} overlaps {self._at[address].name!r} at {address}"
                    )
                self._at[address] = item
            self._by_name[item.name] = item

    def __getitem__(self, name: str) -> ControlItem:
        try:
            return self._by_name[name]
        except KeyError:
            raise KeyError(
                f"no control-table item named {name!r}; names are spelled as the e-Manual prints "
                f"them, e.g. 'Goal Position', 'Present Position', 'Hardware Error Status'"
            ) from None

    def __contains__(self, name: object) -> bool:
        return name in self._by_name

    def item_at(self, address: int) -> ControlItem | None:
        """The item holding byte `address`, or None for an undefined byte."""
        if 0 <= address < self.size_bytes:
            return self._at[address]
        return None


H54_ITEMS: tuple[ControlItem, ...] = _h54_items()
H54_LAYOUT = ControlTableLayout(H54_ITEMS, TABLE_SIZE_BYTES)


def indirect_address_item(n: int) -> str:
    """Name of Indirect Address n (1..256), at 49 + 2(n - 1)."""
    _check_indirect_index(n)
    return f"Indirect Address {n}"


def indirect_data_address(n: int) -> int:
    """Address of Indirect Data n (1..256): 634 + (n - 1)."""
    _check_indirect_index(n)
    return INDIRECT_DATA_BASE + (n - 1)


def _check_indirect_index(n: int) -> None:
    if not 1 <= n <= INDIRECT_COUNT:
        raise ValueError(f"indirect index must be 1..{INDIRECT_COUNT}, got {n}")
