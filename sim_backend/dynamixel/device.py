"""One emulated DYNAMIXEL PRO of any model of the family: its control table and instruction
semantics (the model's table and figures: control_table.py, models.py).

Two faces:
- the protocol face (`ping`, `read`, `write`, `reg_write`, `action`, `reboot`, `factory_reset`,
  `status_error`, `replies_to`), used by `DynamixelChain`, which enforces the access rules of the
  e-Manual and returns the error number of the status packet;
- the firmware face (`item`, `set_item`, `raise_hardware_error`, `clear_hardware_error`,
  `torque_enabled`, `in_shutdown`, `available`, `add_reboot_listener`), used by a physics model
  to publish Present* values and faults. It bypasses the access rules.

The protocol face and the e-Manual's rules it enforces are in `instructions.py`; this module
holds the control table, the firmware face and the indirect-address map.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING

from sim_backend.dynamixel.control_table import (
    FACTORY_BAUD_INDEX,
    HARDWARE_ERROR_BITS_MASK,
    RETURN_DELAY_UNIT_S,
    Access,
    Area,
    ControlItem,
    ControlTableLayout,
    DeviceModel,
    device_model,
)
from sim_backend.dynamixel.instructions import (
    FACTORY_RESET_ALL,
    FACTORY_RESET_ALL_BUT_ID,
    FACTORY_RESET_ALL_BUT_ID_AND_BAUD,
    Bound,
    InstructionSemantics,
)
from sim_backend.dynamixel.models import DEFAULT_MODEL

__all__ = [
    "DEFAULT_FIRMWARE_VERSION",
    "DEFAULT_REBOOT_TIME_S",
    "FACTORY_RESET_ALL",
    "FACTORY_RESET_ALL_BUT_ID",
    "FACTORY_RESET_ALL_BUT_ID_AND_BAUD",
    "DynamixelProDevice",
    "H54Device",
]

if TYPE_CHECKING:
    from sim_backend.servo import Measurements, WriteCounter

# The items `set_measurements` writes, in the order of servo.Measurements' fields.
_MEASUREMENT_ITEMS = (
    "Moving",
    "Present Position",
    "Present Velocity",
    "Present Current",
    "Present Input Voltage",
    "Present Temperature",
)

DEFAULT_FIRMWARE_VERSION = 1  # not published for the legacy Pro; any 0..254 is plausible
DEFAULT_REBOOT_TIME_S = 0.3  # not published; a REBOOT of an X-series takes a few hundred ms


class DynamixelProDevice(InstructionSemantics):
    """One actuator of `model` (e-Manual name or model number; default the H54-200-S500-R): a
    bytearray control table plus the firmware's rules.

    `eeprom_overrides` sets EEPROM items (by e-Manual name) as this unit was configured, e.g.
    {"Return Delay Time": 0, "Max Position Limit": 100_000}; read-only identity items such as
    "Model Number" may be overridden too (a unit that claims another model). A factory reset
    returns the writable ones to the e-Manual values.
    """

    def __init__(
        self,
        dxl_id: int = 1,
        *,
        model: str | int | DeviceModel = DEFAULT_MODEL,
        baud_index: int = FACTORY_BAUD_INDEX,
        firmware_version: int = DEFAULT_FIRMWARE_VERSION,
        eeprom_overrides: Mapping[str, int] | None = None,
        reboot_time_s: float = DEFAULT_REBOOT_TIME_S,
    ) -> None:
        if reboot_time_s < 0:
            raise ValueError(f"reboot_time_s must be >= 0, got {reboot_time_s}")
        self.model = model if isinstance(model, DeviceModel) else device_model(model)
        layout: ControlTableLayout = self.model.layout
        self._layout = layout
        self._indirect = self.model.indirect
        # the special items' addresses on this model (PRO: 562/891/892/890; PRO+: 512/516/518/517)
        self._torque_address = layout["Torque Enable"].address
        self._status_return_address = layout["Status Return Level"].address
        self._hardware_error_address = layout["Hardware Error Status"].address
        self._registered_address = layout["Registered Instruction"].address
        self._goal_position_unlimited_modes = (
            self.model.firmware_items.goal_position_unlimited_modes
        )
        self._table = bytearray(layout.size_bytes)
        self.reboot_time_s = reboot_time_s
        self.silenced = False  # firmware-side fault: the device hears nothing, answers nothing
        self._reboot_until_s = float("-inf")
        self._in_shutdown = False
        self._registered: tuple[int, bytes] | None = None
        self._reboot_listeners: list[Callable[[], None]] = []
        self._indirect_map: list[int] | None = None  # Indirect Address 1..n, cached
        # The firmware writes the Present* items when a read may cover them (see
        # `attach_measurement_source`), not after every physics step.
        self._measurement_source: Callable[[], None] | None = None
        # Changes with every write but the firmware's measurements: the firmware re-decodes
        # its registers only then; only Goal Position when all writes since were WRITEs of
        # exactly Goal Position (counted here: the host's every tick).
        self.revision = 0
        self._write_counters: list[WriteCounter] = []
        self.goal_position_writes = 0
        self._goal_position_address = layout["Goal Position"].address
        # Items that are neither Indirect Data nor Indirect Address: read and written as plain
        # bytes (name -> address, end, size, signed), the fast path of item/set_item.
        indirect = self._indirect
        self._direct_items: dict[str, tuple[int, int, int, bool]] = {
            item.name: (item.address, item.end, item.size, item.signed)
            for item in layout.items
            if not (indirect.data_base <= item.address < indirect.data_end)
            and not (item.end > indirect.address_base and item.address < indirect.address_end)
        }
        # Plain items by (address, size): a write of exactly one of them takes a short path.
        self._whole_items: dict[tuple[int, int], ControlItem] = {
            (item.address, item.size): item
            for item in layout.items
            if item.name in self._direct_items
        }
        self._measured_names = frozenset(item.name for item in layout.items if item.measured)
        self._measurement_packer = MeasurementPacker(
            [self._direct_items[name] for name in _MEASUREMENT_ITEMS], layout
        )
        # Each checked item's Data Limit bounds (e-Manual): a constant, or another plain item
        # read straight from the table (address, end, signed, negated)
        self._limit_bounds: dict[str, tuple[Bound, Bound]] = {
            item.name: (self._bound(item.limit_low), self._bound(item.limit_high))
            for item in layout.items
            if item.limit_low is not None or item.limit_high is not None
        }
        self._operating_mode_address = layout["Operating Mode"].address

        for item in layout.items:
            self._store(item, item.default)
        self._store_checked("ID", dxl_id)
        self._store_checked("Baud Rate", baud_index)
        self._store_checked("Firmware Version", firmware_version)
        for name, value in (eeprom_overrides or {}).items():
            item = layout[name]
            if item.area is not Area.EEPROM:
                raise ValueError(
                    f"eeprom_overrides may only set EEPROM items; {name!r} is in RAM "
                    f"(use set_item for firmware-side RAM values)"
                )
            if item.access is Access.READ_WRITE and not item.in_range(value):
                raise ValueError(
                    f"eeprom_overrides[{name!r}] = {value} is outside its range "
                    f"{item.minimum}..{item.maximum}"
                )
            self._store(item, value)
        self._goal_from_present()

    # ---------------------------------------------------------------- firmware face

    @property
    def dxl_id(self) -> int:
        return self._table[7]

    @property
    def baud_bps(self) -> int:
        """The line speed this device listens and answers at, from Baud Rate (8)."""
        return self.model.baud_rates[self._table[8]]

    @property
    def return_delay_s(self) -> float:
        """Return Delay Time (9) in seconds (2 us per unit)."""
        return self._table[9] * RETURN_DELAY_UNIT_S

    @property
    def status_return_level(self) -> int:
        return self._table[self._status_return_address]

    @property
    def torque_enabled(self) -> bool:
        return self._table[self._torque_address] != 0

    @property
    def in_shutdown(self) -> bool:
        """True after a hardware error enabled in Shutdown (48) until the next REBOOT."""
        return self._in_shutdown

    @property
    def hardware_error_status(self) -> int:
        return self._table[self._hardware_error_address]

    def item(self, name: str) -> int:
        """Decoded value of an item (signed where the item is); Indirect Data follows its map."""
        if self._measurement_source is not None and (
            name in self._measured_names or name not in self._direct_items
        ):
            self._measurement_source()
        direct = self._direct_items.get(name)
        if direct is not None:  # the firmware reads ~15 items per physics step: keep it cheap
            address, end, _, signed = direct
            return int.from_bytes(self._table[address:end], "little", signed=signed)
        item = self._layout[name]
        if self._indirect.data_base <= item.address < self._indirect.data_end:
            return self._table[self._indirect_target(item.address)]
        return item.decode(self._table[item.address : item.end])

    def add_write_counter(self, counter: WriteCounter) -> None:
        """`counter` counts this table's writes too (every step of `revision`): a firmware
        reading many tables sees at once that none was written."""
        self._write_counters.append(counter)

    def _bump(self) -> None:
        self.revision += 1
        for counter in self._write_counters:
            counter.count += 1

    def set_item(self, name: str, value: int) -> None:
        """Firmware-side write: no access, range or limit rules (the value must fit the item)."""
        if name not in self._measured_names:
            self._bump()
        direct = self._direct_items.get(name)
        if direct is not None:
            address, end, size, signed = direct
            try:
                self._table[address:end] = int(value).to_bytes(size, "little", signed=signed)
                return
            except OverflowError:
                pass  # the general path below raises the item's own error message
        item = self._layout[name]
        if self._indirect.data_base <= item.address < self._indirect.data_end:
            self._table[self._indirect_target(item.address)] = item.encode(value)[0]
        else:
            self._store(item, value)

    def set_measurements(self, measurements: Measurements) -> None:
        """Firmware-side: the Present* items after a physics step, in one go (the revision
        stays: they are not the firmware's inputs)."""
        self._measurement_packer.pack_into(self._table, measurements)

    def attach_measurement_source(self, write_measurements: Callable[[], None]) -> None:
        """`write_measurements()` runs before every read that may cover the Present* items (a
        READ, SYNC_READ or BULK_READ, Indirect Data, `item` of a measured item): the firmware
        writes them then with `set_measurements`, if they changed since."""
        self._measurement_source = write_measurements

    def raise_hardware_error(self, bits: int) -> None:
        """OR `bits` into Hardware Error Status (PRO 892, PRO+ 518). Bits also set in Shutdown
        (PRO 48, PRO+ 63) turn torque off and latch the shutdown until REBOOT."""
        if bits & ~HARDWARE_ERROR_BITS_MASK or bits < 0:
            raise ValueError(
                f"hardware error bits must be within 0x{HARDWARE_ERROR_BITS_MASK:02X} "
                f"(bits 7 and 6 are unused), got 0x{bits:X}"
            )
        self._bump()
        self._table[self._hardware_error_address] |= bits
        if bits & self.item("Shutdown"):
            self._table[self._torque_address] = 0
            self._in_shutdown = True

    def clear_hardware_error(self, bits: int) -> None:
        """Clear bits of Hardware Error Status (a non-latched condition went away). The
        shutdown latch stays: only REBOOT clears it."""
        self._bump()
        self._table[self._hardware_error_address] &= ~bits & 0xFF

    def available(self, now_s: float) -> bool:
        """False while rebooting or while silenced by a firmware-side fault."""
        return not self.silenced and now_s >= self._reboot_until_s

    def add_reboot_listener(self, fn: Callable[[], None]) -> None:
        """`fn()` runs after every REBOOT / FACTORY_RESET (RAM is back to initial values)."""
        self._reboot_listeners.append(fn)

    # ---------------------------------------------------------------- internals

    def _store(self, item: ControlItem, value: int) -> None:
        self._bump()
        self._table[item.address : item.end] = item.encode(value)
        if item.end > self._indirect.address_base and item.address < self._indirect.address_end:
            self._indirect_map = None

    def _store_checked(self, name: str, value: int) -> None:
        item = self._layout[name]
        if not item.in_range(value):
            raise ValueError(f"{name} must be {item.minimum}..{item.maximum}, got {value}")
        self._store(item, value)

    def _goal_from_present(self) -> None:
        # Power-on/reboot: hold where the output is (Goal Position has no published initial
        # value; holding the present position is what makes a later torque-on jump-free).
        position = self.item("Present Position")
        self._store(self._layout["Goal Position"], position)

    def _indirect_targets(self) -> list[int]:
        """Indirect Address 1..n as a list (rebuilt after any write to the entries)."""
        if self._indirect_map is None:
            table, indirect = self._table, self._indirect
            self._indirect_map = [
                table[base] | (table[base + 1] << 8)
                for base in range(indirect.address_base, indirect.address_end, 2)
            ]
        return self._indirect_map

    def _indirect_target(self, data_address: int) -> int:
        return self._indirect_targets()[data_address - self._indirect.data_base]

    def _physical(self, address: int) -> int:
        """Where the byte at `address` really lives (Indirect Data follows its map)."""
        if self._indirect.data_base <= address < self._indirect.data_end:
            return self._indirect_target(address)
        return address


# The name the class had while it emulated one model (kept for the code that says so).
H54Device = DynamixelProDevice


class MeasurementPacker:
    """Writes the measured items (in `servo.Measurements`' order) into a table: one
    `pack_into` over the block where they follow each other in address order with only undefined
    bytes between them (the PRO: 610..625), else one per item (PRO+: Present Current 574 lies
    before Present Velocity 576 and Position 580, Moving Status and Present PWM between)."""

    def __init__(self, slots: list[tuple[int, int, int, bool]], layout: ControlTableLayout) -> None:
        codes = {1: "b", 2: "h", 4: "i"}

        def code(size: int, signed: bool) -> str:
            return codes[size] if signed else codes[size].upper()

        self._block: tuple[int, struct.Struct] | None = None
        self._items: list[tuple[int, struct.Struct]] = []
        ordered = all(a[1] <= b[0] for a, b in zip(slots, slots[1:], strict=False))
        gaps_undefined = ordered and all(
            layout.item_at(byte) is None
            for a, b in zip(slots, slots[1:], strict=False)
            for byte in range(a[1], b[0])
        )
        if gaps_undefined:
            fmt, end = "<", slots[0][0]
            for address, item_end, size, signed in slots:
                fmt += "x" * (address - end) + code(size, signed)
                end = item_end
            self._block = (slots[0][0], struct.Struct(fmt))
        else:
            self._items = [
                (address, struct.Struct("<" + code(size, signed)))
                for address, _, size, signed in slots
            ]

    def pack_into(self, table: bytearray, values: Measurements) -> None:
        if self._block is not None:
            address, packer = self._block
            packer.pack_into(table, address, *values)
            return
        for (address, packer), value in zip(self._items, values, strict=True):
            packer.pack_into(table, address, value)
