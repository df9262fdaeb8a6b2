"""The control tables of the DYNAMIXEL PRO family as data, one per model (sim_backend/dynamixel/
models.py holds the figures that differ between models).

Source: ROBOTIS e-Manual, each model's "Control Table of EEPROM Area" / "Control Table of RAM
Area" (https://emanual.robotis.com/docs/en/dxl/pro/<model>/ and .../dxl/p/<model>/, repository
ROBOTIS-GIT/emanual) plus the item includes they pull in (_includes/en/dxl/control_table_*_pro.md
for the legacy PRO, _includes/en/dxl/p/control_table_*.md for PRO(A) and P). The same addresses
appear in ROBOTIS' dynamixel-workbench (items_EXTPRO) and ROBOTIS-Framework (*.device).

Three layouts (`models.Firmware`):
- PRO (legacy, e.g. H54-200-S500-R, model 54024): EEPROM 0..560, RAM 562..892, Indirect Address
  1..256 at 49, Indirect Data 1..256 at 634, Baud Rate 0..8.
- PRO(A) (the "(A)" revisions, e.g. H54-200-S500-R(A), model 54025): EEPROM 0..422, RAM from 512
  (Torque Enable 512, Goal Position 564, Present Position 580), Indirect Address 1..128 at 168,
  Indirect Data 1..128 at 634, Baud Rate 0..9 (9 = 10.5 Mbps, 8 = 6 Mbps).
- P (DYNAMIXEL-P / PRO+, e.g. PH54-200-S500-R, model 2020): the PRO(A) table plus Protocol Type
  (13).

Choices where the e-Manual is silent or inconsistent (the emulator's, documented here):
- Undefined bytes (PRO: 10, 12, 566..585, 590..593, 619..620; PRO+: 14..19, 28..30, 60..62,
  424..511, 519..523, 534..535, 540..545, 547, 595..599, 608..633, 762..1023) read as 0; a write
  touching one is an Access Error. ROBOTIS-Framework lists a "drive_mode" at 10 on the PRO; the
  e-Manual does not, so neither do we.
- PRO Baud Rate range 0..8 (the index table of the include; the main table's "0 ~ 13" has no
  meaning for indices 9..13). PRO+ 0..9 (its include and table agree).
- Return Delay Time range 0..254 (the includes; the PRO and PRO(A) main tables say 0 ~ 255).
- PRO Torque Limit range: each model's table (H54-200-S500-R 0..1860; the generic include says
  0..32,767); models whose range was not read are assumed as `models.ModelFigures.assumed` says.
- PRO Indirect Address range 562..892 (the include: "limited to RAM area (Address 562 ~ 892)";
  the main table's "562 ~ 949" runs past the end of the table). PRO+ 512..1023 (the main table;
  the include's "512 ~ 606" would refuse the item's own initial values 634..761): the PRO+ table
  therefore spans 1024 bytes, 762..1023 undefined.
- Initial values the e-Manual prints as "-": Model Information 0, Goal Position = Present
  Position at power-on and reboot, Present Input Voltage 240 (24.0 V), Present Temperature 30
  degC, the other Present* items, Goal PWM/Current/Velocity and the Profile items 0; the rest
  are each model's assumption (`models.ModelFigures.assumed`). Firmware Version comes from the
  device's constructor.
- PRO External Port Mode initial value 0 (the H54 table; the include marks 3 as default); PRO+
  3 (its tables).
- External Port Data is writable only while its port is in mode 1 (digital output), read-only
  otherwise (the include's access column).
- Goal Acceleration (PRO) must lie in 0..Acceleration Limit (Data Limit Error otherwise).
- Goal Position is checked against Min/Max Position Limit except in Extended Position Control
  Mode (4) on the PRO (the include says the limits are ignored there), and only in Position
  Control Mode (3) on PRO+ ("while ranging -2,147,483,648 ~ 2,147,483,647 in other modes").
- PRO+ items the firmware does not model read as their initial values (Realtime Tick, Moving
  Status, Present PWM, Velocity/Position Trajectory: 0).
"""

from __future__ import annotations

import enum
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from functools import cache
from types import MappingProxyType

from sim_backend.dynamixel.models import (
    DEFAULT_MODEL,
    DeviceUnits,
    Firmware,
    ModelFigures,
    figures_of,
)

MODEL_NUMBER_H54_200_S500_R = 54024  # 0xD308, e-Manual "Model Number(0)"
TABLE_SIZE_BYTES = 893  # the PRO's addresses 0..892; Hardware Error Status is the last item
PRO_PLUS_TABLE_SIZE_BYTES = 1024  # PRO+: Indirect Address may point up to 1,023

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
# PRO+ (include p/control_table_8_baud_rate.md): 8 is 6 Mbps and 10.5 Mbps moves to 9.
PRO_PLUS_BAUD_RATE_BPS: Mapping[int, int] = {
    **{index: bps for index, bps in BAUD_RATE_BPS.items() if index < 8},
    8: 6_000_000,
    9: 10_500_000,
}
FACTORY_BAUD_INDEX = 1  # 57,600 bps on every model

RETURN_DELAY_UNIT_S = 2e-6  # Return Delay Time(9): 2 us per unit

# Hardware Error Status / Shutdown bits (e-Manual include control_table_shutdown.md).
HARDWARE_ERROR_BITS_MASK = 0x3F  # bits 7 and 6 are "not used, always 0"

# The PRO's indirect entries (include control_table_49_indirectdata_pro.md)
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


def _pro_items(m: ModelFigures) -> tuple[ControlItem, ...]:
    """A legacy PRO model's table, address order: EEPROM (0..560), then RAM (562..892)."""
    return (*_pro_eeprom_items(m), *_pro_ram_items(m))


def _pro_eeprom_items(m: ModelFigures) -> list[ControlItem]:
    eeprom = Area.EEPROM
    items = [
        _read_only(eeprom, "Model Number", 0, 2, m.number),
        _read_only(eeprom, "Model Information", 2, 4, 0),
        _read_only(eeprom, "Firmware Version", 6, 1, 0),
        _eeprom("ID", 7, 1, 1, 0, 252),
        _eeprom("Baud Rate", 8, 1, FACTORY_BAUD_INDEX, 0, 8),
        _eeprom("Return Delay Time", 9, 1, 250, 0, 254),
        _eeprom("Operating Mode", 11, 1, 3, 0, 4, allowed_values=frozenset({0, 1, 3, 4})),
        _eeprom("Homing Offset", 13, 4, 0, INT32_MIN, INT32_MAX, signed=True),
        _eeprom("Moving Threshold", 17, 4, m.moving_threshold, 0, INT32_MAX),
        _eeprom("Temperature Limit", 21, 1, 80, 0, 100),
        _eeprom("Max Voltage Limit", 22, 2, m.max_voltage_limit, 0, 400),
        _eeprom("Min Voltage Limit", 24, 2, 150, 0, 400),
        _eeprom("Acceleration Limit", 26, 4, m.acceleration_limit, 0, m.acceleration_limit_max),
        _eeprom("Torque Limit", 30, 2, m.current_limit, 0, m.current_limit_max),
        _eeprom("Velocity Limit", 32, 4, m.velocity_limit, 0, m.velocity_limit_max),
        _eeprom("Max Position Limit", 36, 4, m.max_position, INT32_MIN, INT32_MAX, signed=True),
        _eeprom("Min Position Limit", 40, 4, -m.max_position, INT32_MIN, INT32_MAX, signed=True),
    ]
    items += [_eeprom(f"External Port Mode {k}", 43 + k, 1, 0, 0, 3) for k in range(1, 5)]
    items.append(_eeprom("Shutdown", 48, 1, m.shutdown, 0, 255))
    items += _indirect_addresses(PRO_INDIRECT)
    return items


def _pro_ram_items(m: ModelFigures) -> list[ControlItem]:
    ram = Area.RAM
    items = [
        _ram("Torque Enable", 562, 1, 0, 0, 1),
        _ram("LED Red", 563, 1, 0, 0, 255),
        _ram("LED Green", 564, 1, 0, 0, 255),
        _ram("LED Blue", 565, 1, 0, 0, 255),
        _ram("Velocity I Gain", 586, 2, m.gains.velocity_i, 0, 65_535),
        _ram("Velocity P Gain", 588, 2, m.gains.velocity_p, 0, 65_535),
        _ram("Position P Gain", 594, 2, m.gains.position_p, 0, 65_535),
        _goal_position(596),
        _bounded("Goal Velocity", 600, 4, "Velocity Limit"),
        _bounded("Goal Torque", 604, 2, "Torque Limit"),
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
    items += _external_port_data(624)
    items += _indirect_data(PRO_INDIRECT)
    items += [
        _read_only(ram, "Registered Instruction", 890, 1, 0),
        _ram("Status Return Level", 891, 1, 2, 0, 2),
        _read_only(ram, "Hardware Error Status", 892, 1, 0),
    ]
    return items


def _pro_plus_items(m: ModelFigures) -> tuple[ControlItem, ...]:
    """A PRO(A) or P model's table (P: plus Protocol Type 13), address order."""
    return (*_pro_plus_eeprom_items(m), *_pro_plus_ram_items(m))


def _pro_plus_eeprom_items(m: ModelFigures) -> list[ControlItem]:
    eeprom = Area.EEPROM
    position = m.position_limit
    items = [
        _read_only(eeprom, "Model Number", 0, 2, m.number),
        _read_only(eeprom, "Model Information", 2, 4, 0),
        _read_only(eeprom, "Firmware Version", 6, 1, 0),
        _eeprom("ID", 7, 1, 1, 0, 252),
        _eeprom("Baud Rate", 8, 1, FACTORY_BAUD_INDEX, 0, 9),
        _eeprom("Return Delay Time", 9, 1, 250, 0, 254),
        _eeprom("Drive Mode", 10, 1, 0, 0, 1),
        _eeprom("Operating Mode", 11, 1, 3, 0, 16, allowed_values=frozenset({0, 1, 3, 4, 16})),
        _eeprom("Secondary ID", 12, 1, 255, 0, 255),
    ]
    if m.firmware is Firmware.P:
        items.append(_eeprom("Protocol Type", 13, 1, 2, 2, 10, allowed_values=frozenset({2, 10})))
    items += [
        _eeprom("Homing Offset", 20, 4, 0, INT32_MIN, INT32_MAX, signed=True),
        _eeprom("Moving Threshold", 24, 4, m.moving_threshold, 0, m.velocity_limit_max),
        _eeprom("Temperature Limit", 31, 1, 80, 0, 100),
        _eeprom("Max Voltage Limit", 32, 2, m.max_voltage_limit, 150, 350),
        _eeprom("Min Voltage Limit", 34, 2, 150, 150, 350),
        _eeprom("PWM Limit", 36, 2, 2009, 0, 2009),
        _eeprom("Current Limit", 38, 2, m.current_limit, 0, m.current_limit_max),
        _eeprom("Acceleration Limit", 40, 4, m.acceleration_limit, 0, m.acceleration_limit_max),
        _eeprom("Velocity Limit", 44, 4, m.velocity_limit, 0, m.velocity_limit_max),
        _eeprom("Max Position Limit", 48, 4, m.max_position, -position, position, signed=True),
        _eeprom("Min Position Limit", 52, 4, -m.max_position, -position, position, signed=True),
    ]
    items += [_eeprom(f"External Port Mode {k}", 55 + k, 1, 3, 0, 3) for k in range(1, 5)]
    items.append(_eeprom("Shutdown", 63, 1, m.shutdown, 0, 255))
    items += _indirect_addresses(PRO_PLUS_INDIRECT)
    return items


def _pro_plus_ram_items(m: ModelFigures) -> list[ControlItem]:
    ram = Area.RAM
    items = [
        _ram("Torque Enable", 512, 1, 0, 0, 1),
        _ram("LED Red", 513, 1, 0, 0, 255),
        _ram("LED Green", 514, 1, 0, 0, 255),
        _ram("LED Blue", 515, 1, 0, 0, 255),
        _ram("Status Return Level", 516, 1, 2, 0, 2),
        _read_only(ram, "Registered Instruction", 517, 1, 0),
        _read_only(ram, "Hardware Error Status", 518, 1, 0),
        _ram("Velocity I Gain", 524, 2, m.gains.velocity_i, 0, 32_767),
        _ram("Velocity P Gain", 526, 2, m.gains.velocity_p, 0, 32_767),
        _ram("Position D Gain", 528, 2, 0, 0, 32_767),
        _ram("Position I Gain", 530, 2, 0, 0, 32_767),
        _ram("Position P Gain", 532, 2, m.gains.position_p, 0, 32_767),
        _ram("Feedforward 2nd Gain", 536, 2, 0, 0, 32_767),
        _ram("Feedforward 1st Gain", 538, 2, 0, 0, 32_767),
        _ram("Bus Watchdog", 546, 1, 0, 0, 127),
        _bounded("Goal PWM", 548, 2, "PWM Limit"),
        _bounded("Goal Current", 550, 2, "Current Limit"),
        _bounded("Goal Velocity", 552, 4, "Velocity Limit"),
        _ram("Profile Acceleration", 556, 4, 0, 0, INT32_MAX, limit_high="Acceleration Limit"),
        _ram("Profile Velocity", 560, 4, 0, 0, INT32_MAX, limit_high="Velocity Limit"),
        _goal_position(564),
        _read_only(ram, "Realtime Tick", 568, 2, 0, measured=True),
        _read_only(ram, "Moving", 570, 1, 0, measured=True),
        _read_only(ram, "Moving Status", 571, 1, 0, measured=True),
        _read_only(ram, "Present PWM", 572, 2, 0, signed=True, measured=True),
        _read_only(ram, "Present Current", 574, 2, 0, signed=True, measured=True),
        _read_only(ram, "Present Velocity", 576, 4, 0, signed=True, measured=True),
        _read_only(ram, "Present Position", 580, 4, 0, signed=True, measured=True),
        _read_only(ram, "Velocity Trajectory", 584, 4, 0, signed=True, measured=True),
        _read_only(ram, "Position Trajectory", 588, 4, 0, signed=True, measured=True),
        _read_only(ram, "Present Input Voltage", 592, 2, 240, measured=True),
        _read_only(ram, "Present Temperature", 594, 1, 30, measured=True),
    ]
    items += _external_port_data(598)
    items += _indirect_data(PRO_PLUS_INDIRECT)
    return items


def _goal_position(address: int) -> ControlItem:
    return _ram(
        "Goal Position",
        address,
        4,
        0,
        INT32_MIN,
        INT32_MAX,
        signed=True,
        limit_low="Min Position Limit",
        limit_high="Max Position Limit",
    )


def _bounded(name: str, address: int, size: int, limit: str) -> ControlItem:
    """A signed goal bounded by +-`limit` (Data Limit Error outside it)."""
    low, high = -(2 ** (8 * size - 1)), 2 ** (8 * size - 1) - 1
    return _ram(
        name, address, size, 0, low, high, signed=True, limit_low=f"-{limit}", limit_high=limit
    )


def _external_port_data(base: int) -> list[ControlItem]:
    """External Port Data 1..4 at base + 2k, writable while its port is in mode 1."""
    return [
        _ram(
            f"External Port Data {k}",
            base + 2 * k,
            2,
            0,
            0,
            4095,
            writable_when=(f"External Port Mode {k}", 1),
        )
        for k in range(1, 5)
    ]


@dataclass(frozen=True)
class IndirectMap:
    """Indirect Address n at address_base + 2(n - 1) (2 bytes, EEPROM, holds the address of ONE
    byte, initial value data_base + (n - 1)); Indirect Data n at data_base + (n - 1) reads and
    writes that byte. Targets must lie in target_min..target_max."""

    address_base: int
    data_base: int
    count: int
    target_min: int
    target_max: int

    @property
    def address_end(self) -> int:
        return self.address_base + 2 * self.count

    @property
    def data_end(self) -> int:
        return self.data_base + self.count


PRO_INDIRECT = IndirectMap(
    INDIRECT_ADDRESS_BASE,
    INDIRECT_DATA_BASE,
    INDIRECT_COUNT,
    INDIRECT_TARGET_MIN,
    INDIRECT_TARGET_MAX,
)
# PRO+ (PRO(A)/P tables, include p/control_table_168_indirect.md): 1..128 at 168 / 634.
PRO_PLUS_INDIRECT = IndirectMap(168, 634, 128, 512, 1023)


def _indirect_addresses(indirect: IndirectMap) -> list[ControlItem]:
    return [
        _eeprom(
            f"Indirect Address {n}",
            indirect.address_base + 2 * (n - 1),
            2,
            indirect.data_base + (n - 1),
            indirect.target_min,
            indirect.target_max,
        )
        for n in range(1, indirect.count + 1)
    ]


def _indirect_data(indirect: IndirectMap) -> list[ControlItem]:
    return [
        _ram(f"Indirect Data {n}", indirect.data_base + (n - 1), 1, 0, 0, 255)
        for n in range(1, indirect.count + 1)
    ]


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


@dataclass(frozen=True)
class FirmwareItems:
    """Which items the servo firmware reads for its limits (their names differ by layout).

    current_limit / goal_current: the current cap and the torque-mode goal.
    speed_cap: the item whose non-zero value caps the speed in position modes (else Velocity
        Limit): Goal Velocity on the PRO (e-Manual "Goal Velocity(600)"), Profile Velocity on
        PRO+ (its position modes run a profile).
    goal_current_caps_every_mode: the PRO's Goal Torque caps the torque in every mode
        ("Goal Torque(604)"); PRO+'s Goal Current acts only in current mode.
    goal_position_unlimited_modes: Operating Modes in which Goal Position ignores the
        Min/Max Position Limit.
    """

    current_limit: str
    goal_current: str
    speed_cap: str
    goal_current_caps_every_mode: bool
    goal_position_unlimited_modes: frozenset[int]


PRO_FIRMWARE_ITEMS = FirmwareItems(
    "Torque Limit", "Goal Torque", "Goal Velocity", True, frozenset({4})
)
PRO_PLUS_FIRMWARE_ITEMS = FirmwareItems(
    "Current Limit", "Goal Current", "Profile Velocity", False, frozenset({0, 1, 4, 16})
)


@dataclass(frozen=True)
class DeviceModel:
    """Everything an emulated device needs about its model: figures, table, where its special
    items live, its baud rates and its indirect map."""

    figures: ModelFigures
    layout: ControlTableLayout
    baud_rates: Mapping[int, int]
    indirect: IndirectMap
    firmware_items: FirmwareItems

    @property
    def name(self) -> str:
        return self.figures.name

    @property
    def number(self) -> int:
        return self.figures.number

    @property
    def units(self) -> DeviceUnits:
        return self.figures.units

    def baud_index(self, baudrate: int) -> int:
        """The Baud Rate item value of `baudrate`; ValueError naming the model's rates."""
        for index, bps in self.baud_rates.items():
            if bps == baudrate:
                return index
        raise ValueError(
            f"the {self.name} cannot run at {baudrate} bps; its Baud Rate item offers "
            f"{sorted(self.baud_rates.values())}"
        )


@cache
def device_model(model: str | int = DEFAULT_MODEL) -> DeviceModel:
    """The `DeviceModel` of a model's e-Manual name or number (built once); ValueError naming
    the models served (or why a known one is refused)."""
    figures = figures_of(model)
    if figures.firmware is Firmware.PRO:
        return DeviceModel(
            figures,
            ControlTableLayout(_pro_items(figures), TABLE_SIZE_BYTES),
            MappingProxyType(dict(BAUD_RATE_BPS)),
            PRO_INDIRECT,
            PRO_FIRMWARE_ITEMS,
        )
    return DeviceModel(
        figures,
        ControlTableLayout(_pro_plus_items(figures), PRO_PLUS_TABLE_SIZE_BYTES),
        MappingProxyType(dict(PRO_PLUS_BAUD_RATE_BPS)),
        PRO_PLUS_INDIRECT,
        PRO_PLUS_FIRMWARE_ITEMS,
    )


H54_MODEL = device_model(DEFAULT_MODEL)
H54_LAYOUT = H54_MODEL.layout
H54_ITEMS: tuple[ControlItem, ...] = H54_LAYOUT.items


def indirect_address_item(n: int) -> str:
    """Name of Indirect Address n (1..256 on the PRO; 1..128 on PRO+)."""
    _check_indirect_index(n)
    return f"Indirect Address {n}"


def indirect_data_address(n: int, indirect: IndirectMap = PRO_INDIRECT) -> int:
    """Address of Indirect Data n: 634 + (n - 1) on every model."""
    _check_indirect_index(n, indirect)
    return indirect.data_base + (n - 1)


def _check_indirect_index(n: int, indirect: IndirectMap = PRO_INDIRECT) -> None:
    if not 1 <= n <= indirect.count:
        raise ValueError(f"indirect index must be 1..{indirect.count}, got {n}")
