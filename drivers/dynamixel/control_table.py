"""Control tables of the DYNAMIXEL PRO family, as plain data keyed by model number.

Only the items this driver uses are listed, under the driver's names for them (the legacy PRO
e-Manual's: "Torque Limit", "Goal Torque"); `ControlItem.name` is the model's own ("Current
Limit", "Goal Current" on PRO+). Every model has every name of `REGISTERS`.

Two layouts (`models.Layout`), from the e-Manual:
- PRO, e.g. the H54-200-S500-R (model number 54024 = 0xD308): https://emanual.robotis.com/docs/
  en/dxl/pro/h54-200-s500-r/ ("Control Table of EEPROM Area" / "Control Table of RAM Area" and
  the item includes); the same addresses are in ROBOTIS dynamixel-workbench `items_EXTPRO`.
- PRO+, the "(A)" revisions and the DYNAMIXEL-P, e.g. the H54-200-S500-R(A) (54025) and the
  PH54-200-S500-R (2020): .../dxl/pro/h54-200-s500-ra/, .../dxl/p/ph54-200-s500-r/ (Torque
  Enable 512, Goal Position 564, 1,003,846 pulse/rev); the same addresses are in
  ROBOTIS-Framework's H54-200-S500-R(A).device.

Each model's units and caps are its row of drivers/dynamixel/models.py. Another model of a
known layout is added by adding a row there, nothing else.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

from drivers.dynamixel.models import ACTUATOR_MODELS, REFUSED, ActuatorModel, Layout
from drivers.dynamixel.units import DeviceUnits, units_of


@dataclass(frozen=True)
class ControlItem:
    """One control-table item: where it is and how its bytes decode (little endian)."""

    name: str
    address: int
    size: int  # bytes: 1, 2 or 4
    signed: bool = False
    writable: bool = True


@dataclass(frozen=True)
class ModelSpec:
    """What the driver needs to know about one actuator model.

    ram_start_address: items below it are EEPROM (writable only with Torque Enable = 0).
    indirect_address_first / indirect_data_first / indirect_count: Indirect Address n is at
        indirect_address_first + 2 (n - 1) (2 bytes, holds a target address, maps ONE byte);
        Indirect Data n is at indirect_data_first + (n - 1).
    indirect_target_range: the addresses an Indirect Address may point to (inclusive).
    baud_rates_bps: Baud Rate item value -> bits per second.
    torque_limit_max_raw: the largest Torque Limit (PRO+: Current Limit) value the table admits.
    gain_max_raw: the largest value of a gain register.
    """

    model_number: int
    model_name: str
    layout: Layout
    units: DeviceUnits
    items: Mapping[str, ControlItem]
    ram_start_address: int
    indirect_address_first: int
    indirect_data_first: int
    indirect_count: int
    indirect_target_range: tuple[int, int]
    baud_rates_bps: Mapping[int, int]
    torque_limit_max_raw: int
    gain_max_raw: int
    position_mode: int  # Operating Mode value of (single-turn) position control

    def item(self, name: str) -> ControlItem:
        try:
            return self.items[name]
        except KeyError:
            raise KeyError(
                f"{self.model_name} has no control-table item {name!r}; "
                f"known: {', '.join(self.items)}"
            ) from None

    def is_eeprom(self, item: ControlItem) -> bool:
        return item.address < self.ram_start_address

    def indirect_address_of(self, index: int) -> int:
        """Address of Indirect Address `index` (1-based)."""
        self._check_indirect_index(index)
        return self.indirect_address_first + 2 * (index - 1)

    def indirect_data_of(self, index: int) -> int:
        """Address of Indirect Data `index` (1-based)."""
        self._check_indirect_index(index)
        return self.indirect_data_first + (index - 1)

    def _check_indirect_index(self, index: int) -> None:
        if not 1 <= index <= self.indirect_count:
            raise ValueError(
                f"indirect index must be in 1..{self.indirect_count} on {self.model_name}, "
                f"got {index}"
            )


def _table(*items: tuple[str, ControlItem]) -> Mapping[str, ControlItem]:
    return MappingProxyType(dict(items))


def _same(item: ControlItem) -> tuple[str, ControlItem]:
    """An item the driver calls by the model's own name."""
    return item.name, item


# The driver's register names: every model's table has each (a test checks it).
REGISTERS: tuple[str, ...] = (
    "Model Number",
    "Firmware Version",
    "ID",
    "Baud Rate",
    "Return Delay Time",
    "Operating Mode",
    "Homing Offset",
    "Torque Limit",
    "Velocity Limit",
    "Max Position Limit",
    "Min Position Limit",
    "Shutdown",
    "Torque Enable",
    "Velocity I Gain",
    "Velocity P Gain",
    "Position P Gain",
    "Goal Position",
    "Goal Velocity",
    "Goal Torque",
    "Present Position",
    "Present Velocity",
    "Present Current",
    "Present Input Voltage",
    "Present Temperature",
    "Status Return Level",
    "Hardware Error Status",
)

_PRO_ITEMS = _table(
    # EEPROM area
    _same(ControlItem("Model Number", 0, 2, writable=False)),
    _same(ControlItem("Firmware Version", 6, 1, writable=False)),
    _same(ControlItem("ID", 7, 1)),
    _same(ControlItem("Baud Rate", 8, 1)),
    _same(ControlItem("Return Delay Time", 9, 1)),  # x 2 us, default 250 (500 us)
    _same(ControlItem("Operating Mode", 11, 1)),  # 0 torque, 1 velocity, 3 position, 4 ext.
    _same(ControlItem("Homing Offset", 13, 4, signed=True)),
    _same(ControlItem("Torque Limit", 30, 2)),  # x the current unit (16.11328 mA on the H54)
    _same(ControlItem("Velocity Limit", 32, 4)),  # x the velocity unit
    _same(ControlItem("Max Position Limit", 36, 4, signed=True)),
    _same(ControlItem("Min Position Limit", 40, 4, signed=True)),
    _same(ControlItem("Shutdown", 48, 1)),  # bit mask as Hardware Error Status, default 58
    # RAM area
    _same(ControlItem("Torque Enable", 562, 1)),
    _same(ControlItem("Velocity I Gain", 586, 2)),
    _same(ControlItem("Velocity P Gain", 588, 2)),
    _same(ControlItem("Position P Gain", 594, 2)),
    _same(ControlItem("Goal Position", 596, 4, signed=True)),
    _same(ControlItem("Goal Velocity", 600, 4, signed=True)),
    _same(ControlItem("Goal Torque", 604, 2, signed=True)),
    _same(ControlItem("Present Position", 611, 4, signed=True, writable=False)),
    _same(ControlItem("Present Velocity", 615, 4, signed=True, writable=False)),
    _same(ControlItem("Present Current", 621, 2, signed=True, writable=False)),
    _same(ControlItem("Present Input Voltage", 623, 2, writable=False)),  # x 0.1 V
    _same(ControlItem("Present Temperature", 625, 1, writable=False)),  # deg C
    _same(ControlItem("Status Return Level", 891, 1)),  # 0 ping only, 1 + read, 2 all
    _same(ControlItem("Hardware Error Status", 892, 1, writable=False)),  # e-Manual: 1 byte
)

_PRO_PLUS_ITEMS = _table(
    # EEPROM area
    _same(ControlItem("Model Number", 0, 2, writable=False)),
    _same(ControlItem("Firmware Version", 6, 1, writable=False)),
    _same(ControlItem("ID", 7, 1)),
    _same(ControlItem("Baud Rate", 8, 1)),
    _same(ControlItem("Return Delay Time", 9, 1)),  # x 2 us, default 250 (500 us)
    _same(ControlItem("Operating Mode", 11, 1)),  # 0 current, 1 velocity, 3 position, 4, 16
    _same(ControlItem("Homing Offset", 20, 4, signed=True)),
    ("Torque Limit", ControlItem("Current Limit", 38, 2)),  # x 1 mA
    _same(ControlItem("Velocity Limit", 44, 4)),  # x 0.01 rev/min
    _same(ControlItem("Max Position Limit", 48, 4, signed=True)),
    _same(ControlItem("Min Position Limit", 52, 4, signed=True)),
    _same(ControlItem("Shutdown", 63, 1)),
    # RAM area
    _same(ControlItem("Torque Enable", 512, 1)),
    _same(ControlItem("Status Return Level", 516, 1)),
    _same(ControlItem("Hardware Error Status", 518, 1, writable=False)),
    _same(ControlItem("Velocity I Gain", 524, 2)),
    _same(ControlItem("Velocity P Gain", 526, 2)),
    _same(ControlItem("Position P Gain", 532, 2)),
    ("Goal Torque", ControlItem("Goal Current", 550, 2, signed=True)),  # x 1 mA
    _same(ControlItem("Goal Velocity", 552, 4, signed=True)),
    _same(ControlItem("Goal Position", 564, 4, signed=True)),
    _same(ControlItem("Present Current", 574, 2, signed=True, writable=False)),
    _same(ControlItem("Present Velocity", 576, 4, signed=True, writable=False)),
    _same(ControlItem("Present Position", 580, 4, signed=True, writable=False)),
    _same(ControlItem("Present Input Voltage", 592, 2, writable=False)),  # x 0.1 V
    _same(ControlItem("Present Temperature", 594, 1, writable=False)),  # deg C
)

# e-Manual include control_table_8_baudrate_pro.md
_PRO_BAUD_RATES = MappingProxyType(
    {
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
)
# e-Manual include p/control_table_8_baud_rate.md: 8 is 6 Mbps, 10.5 Mbps moves to 9
_PRO_PLUS_BAUD_RATES = MappingProxyType(
    {**{k: v for k, v in _PRO_BAUD_RATES.items() if k < 8}, 8: 6_000_000, 9: 10_500_000}
)


@dataclass(frozen=True)
class _LayoutFacts:
    """What a layout fixes for every model of it (the rest is the model's row)."""

    items: Mapping[str, ControlItem]
    ram_start_address: int
    indirect_address_first: int
    indirect_count: int
    indirect_target_range: tuple[int, int]
    baud_rates_bps: Mapping[int, int]
    gain_max_raw: int


_LAYOUTS: Mapping[Layout, _LayoutFacts] = MappingProxyType(
    {
        # include control_table_49_indirectdata_pro: Indirect Address 1..256 at 49..559
        # (defaults 634..889), Indirect Data 1..256 at 634..889, targets limited to 562..892.
        # Gains 0..65,535 (the PRO tables; the include says 0 ~ 32,767).
        Layout.PRO: _LayoutFacts(_PRO_ITEMS, 562, 49, 256, (562, 892), _PRO_BAUD_RATES, 65_535),
        # PRO+ tables: Indirect Address 1..128 at 168..422, Indirect Data 1..128 at 634..761,
        # the table's range 512 ~ 1,023; gains 0 ~ 32,767.
        Layout.PRO_PLUS: _LayoutFacts(
            _PRO_PLUS_ITEMS, 512, 168, 128, (512, 1023), _PRO_PLUS_BAUD_RATES, 32_767
        ),
    }
)


def _spec(model: ActuatorModel) -> ModelSpec:
    """A model's `ModelSpec`: its layout's items and indirect map, its row's units and caps."""
    facts = _LAYOUTS[model.layout]
    return ModelSpec(
        model_number=model.number,
        model_name=model.name,
        layout=model.layout,
        units=units_of(model),
        items=facts.items,
        ram_start_address=facts.ram_start_address,
        indirect_address_first=facts.indirect_address_first,
        indirect_data_first=634,  # Indirect Data 1 on every model
        indirect_count=facts.indirect_count,
        indirect_target_range=facts.indirect_target_range,
        baud_rates_bps=facts.baud_rates_bps,
        torque_limit_max_raw=model.current_cap_raw,
        gain_max_raw=facts.gain_max_raw,
        position_mode=3,  # Position Control Mode on every model
    )


MODELS: Mapping[int, ModelSpec] = MappingProxyType(
    {number: _spec(model) for number, model in ACTUATOR_MODELS.items()}
)
H54_200_S500_R = MODELS[54024]
DEFAULT_MODEL_NUMBER = H54_200_S500_R.model_number


def _refusal(model_number: int) -> str:
    refused = REFUSED.get(model_number)
    if refused is not None:
        name, reason = refused
        return f"Dynamixel model {model_number} ({name}) is not supported by this driver: {reason}"
    known = ", ".join(f"{number} ({spec.model_name})" for number, spec in MODELS.items())
    return (
        f"Dynamixel model number {model_number} is not supported by this driver; supported: {known}"
    )


def model_spec(model_number: int) -> ModelSpec:
    """The `ModelSpec` of a model number, or a clear error naming the supported ones (or why a
    model of the family is refused)."""
    try:
        return MODELS[model_number]
    except KeyError:
        raise ValueError(_refusal(model_number)) from None


def model_number(model_name: str) -> int:
    """The model number of a supported model's e-Manual name ('H54-200-S500-R' -> 54024)."""
    for number, spec in MODELS.items():
        if spec.model_name == model_name:
            return number
    for number, (name, _) in REFUSED.items():
        if name == model_name:
            raise ValueError(_refusal(number))
    known = ", ".join(repr(spec.model_name) for spec in MODELS.values())
    raise ValueError(f"Dynamixel model {model_name!r} is not supported; supported: {known}")


def model_name(model_number: int) -> str:
    """A display name for any model number (also unsupported ones, for `scan`)."""
    spec = MODELS.get(model_number)
    if spec is not None:
        return spec.model_name
    refused = REFUSED.get(model_number)
    if refused is not None:
        return f"{refused[0]} (not supported)"
    return f"unknown model {model_number}"
