"""Control tables of the supported Dynamixel models, as plain data keyed by model number.

Only the items this driver uses are listed. Source for the H54-200-S500-R (legacy Dynamixel Pro,
model number 54024 = 0xD308): ROBOTIS e-Manual, https://emanual.robotis.com/docs/en/dxl/pro/
h54-200-s500-r/ ("Control Table of EEPROM Area" / "Control Table of RAM Area" and the item
includes); the same addresses are in ROBOTIS dynamixel-workbench `items_EXTPRO`.

Do not confuse it with the H54-200-S500-R(A), model 54025, whose table differs (Torque Enable 512,
Goal Position 564, 1,003,846 pulse/rev). Another model is added by adding a `ModelSpec` to
`MODELS`, nothing else.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

from drivers.dynamixel.units import H54_200_S500_R_UNITS, DeviceUnits


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
    torque_limit_max_raw: the largest Torque Limit value the table admits.
    """

    model_number: int
    model_name: str
    units: DeviceUnits
    items: Mapping[str, ControlItem]
    ram_start_address: int
    indirect_address_first: int
    indirect_data_first: int
    indirect_count: int
    indirect_target_range: tuple[int, int]
    baud_rates_bps: Mapping[int, int]
    torque_limit_max_raw: int
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


def _table(*items: ControlItem) -> Mapping[str, ControlItem]:
    return MappingProxyType({item.name: item for item in items})


H54_200_S500_R = ModelSpec(
    model_number=54024,
    model_name="H54-200-S500-R",
    units=H54_200_S500_R_UNITS,
    items=_table(
        # EEPROM area
        ControlItem("Model Number", 0, 2, writable=False),
        ControlItem("Firmware Version", 6, 1, writable=False),
        ControlItem("ID", 7, 1),
        ControlItem("Baud Rate", 8, 1),
        ControlItem("Return Delay Time", 9, 1),  # x 2 us, default 250 (500 us)
        ControlItem("Operating Mode", 11, 1),  # 0 torque, 1 velocity, 3 position, 4 ext. pos.
        ControlItem("Homing Offset", 13, 4, signed=True),
        ControlItem("Torque Limit", 30, 2),  # x 16.11328 mA, default 620
        ControlItem("Velocity Limit", 32, 4),  # x 0.00199234 rpm
        ControlItem("Max Position Limit", 36, 4, signed=True),
        ControlItem("Min Position Limit", 40, 4, signed=True),
        ControlItem("Shutdown", 48, 1),  # bit mask as Hardware Error Status, default 58
        # RAM area
        ControlItem("Torque Enable", 562, 1),
        ControlItem("Velocity I Gain", 586, 2),
        ControlItem("Velocity P Gain", 588, 2),
        ControlItem("Position P Gain", 594, 2),
        ControlItem("Goal Position", 596, 4, signed=True),
        ControlItem("Goal Velocity", 600, 4, signed=True),
        ControlItem("Goal Torque", 604, 2, signed=True),
        ControlItem("Present Position", 611, 4, signed=True, writable=False),
        ControlItem("Present Velocity", 615, 4, signed=True, writable=False),
        ControlItem("Present Current", 621, 2, signed=True, writable=False),
        ControlItem("Present Input Voltage", 623, 2, writable=False),  # x 0.1 V
        ControlItem("Present Temperature", 625, 1, writable=False),  # deg C
        ControlItem("Status Return Level", 891, 1),  # 0 ping only, 1 + read, 2 all
        ControlItem("Hardware Error Status", 892, 1, writable=False),  # e-Manual: 1 byte
    ),
    ram_start_address=562,
    # e-Manual include control_table_49_indirectdata_pro: Indirect Address 1..256 at 49..559
    # (defaults 634..889), Indirect Data 1..256 at 634..889, targets limited to 562..892.
    indirect_address_first=49,
    indirect_data_first=634,
    indirect_count=256,
    indirect_target_range=(562, 892),
    # e-Manual include control_table_8_baudrate_pro.
    baud_rates_bps=MappingProxyType(
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
    ),
    # e-Manual main table range of Torque Limit (30): 0..1860 (~30 A). The include says
    # 0..32,767; the narrower figure is the safe one to enforce.
    torque_limit_max_raw=1860,
    position_mode=3,
)

MODELS: Mapping[int, ModelSpec] = MappingProxyType({H54_200_S500_R.model_number: H54_200_S500_R})


def model_spec(model_number: int) -> ModelSpec:
    """The `ModelSpec` of a model number, or a clear error naming the supported ones."""
    try:
        return MODELS[model_number]
    except KeyError:
        known = ", ".join(f"{number} ({spec.model_name})" for number, spec in MODELS.items())
        raise ValueError(
            f"Dynamixel model number {model_number} is not supported by this driver; "
            f"supported: {known}"
        ) from None


# Names of models a scan may meet but this driver does not drive (display only).
# Source: ROBOTIS e-Manual page h54-200-s500-ra (model number 54025).
def model_number(model_name: str) -> int:
    """The model number of a supported model's name ('H54-200-S500-R' -> 54024)."""
    for number, spec in MODELS.items():
        if spec.model_name == model_name:
            return number
    known = ", ".join(repr(spec.model_name) for spec in MODELS.values())
    raise ValueError(f"Dynamixel model {model_name!r} is not supported; supported: {known}")


OTHER_MODEL_NAMES: Mapping[int, str] = MappingProxyType({54025: "H54-200-S500-R(A)"})


def model_name(model_number: int) -> str:
    """A display name for any model number (also unsupported ones, for `scan`)."""
    spec = MODELS.get(model_number)
    if spec is not None:
        return spec.model_name
    return OTHER_MODEL_NAMES.get(model_number, f"unknown model {model_number}")
