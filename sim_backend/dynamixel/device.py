"""One emulated Dynamixel Pro H54-200-S500-R: its control table and instruction semantics.

Two faces:
- the protocol face (`ping`, `read`, `write`, `reg_write`, `action`, `reboot`, `factory_reset`,
  `status_error`, `replies_to`), used by `DynamixelChain`, which enforces the access rules of the
  e-Manual and returns the error number of the status packet;
- the firmware face (`item`, `set_item`, `raise_hardware_error`, `clear_hardware_error`,
  `torque_enabled`, `in_shutdown`, `available`, `add_reboot_listener`), used by a physics model
  to publish Present* values and faults. It bypasses the access rules.

Rules (ROBOTIS e-Manual "Protocol 2.0" Status Packet/Instruction Details and the H54 page):
- EEPROM items are written only while Torque Enable = 0, else Access Error (7).
- Read-only or undefined addresses: Access Error (7). A READ may span undefined bytes of the
  table (they read as 0); a READ past the end of the table is an Access Error with no data.
- Data Length Error (5): a write that covers only part of an item (also through indirect data).
- Data Range Error (4): a value outside the item's range.
- Data Limit Error (6): Goal Position outside Min/Max Position Limit (36/40), Goal Velocity
  beyond +-Velocity Limit (32), Goal Torque beyond +-Torque Limit (30), Goal Acceleration
  outside 0..Acceleration Limit (26).
- A write with any error changes nothing (all of it or none of it). Checks in this order:
  access, length, range, limit, shutdown.
- Alert bit 0x80 in every status packet while Hardware Error Status != 0.
- Shutdown (48): a hardware error whose bit is enabled there clears Torque Enable; only a REBOOT
  brings torque back ("REBOOT is the only method to reset Torque Enable to '1'"). Not documented:
  the reply to Torque Enable = 1 while shut down. This emulator refuses it with Result Fail (1)
  (plus the alert bit) and leaves torque off.
- REG_WRITE is checked when it arrives (errors are reported then and nothing is registered) and
  again when ACTION executes it. ACTION without a registered write: Instruction Error (2).
- REBOOT: the status packet is built first (with the pre-reboot alert bit); then RAM returns to
  its initial values (Torque Enable 0, Hardware Error Status 0, Registered Instruction 0, Status
  Return Level 2, Goal Position = Present Position; measured Present* values are kept), the
  shutdown latch clears, reboot listeners run, and the device stays silent for `reboot_time_s`
  (how long a real H54 takes is not published; a parameter).
- FACTORY_RESET 0xFF / 0x01 / 0x02: EEPROM back to the e-Manual initial values (all / all but
  ID / all but ID and Baud Rate), read-only identity items (model, firmware) kept, then as
  REBOOT. Another option byte: Data Range Error (4). With Torque Enable = 1 it is refused with
  Access Error (7) like any EEPROM write (the e-Manual does not say; the ROM lock does).
  Broadcast with 0xFF is ignored (e-Manual; the chain handles broadcast).
- Indirect Data n reads/writes the byte at Indirect Address n, inheriting that item's size,
  range and access (include control_table_49_indirectdata_pro.md). An Indirect Address that
  points at an Indirect Data byte reaches that byte's own storage (one level only: no loops).
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING

from sim_backend.dynamixel.control_table import (
    BAUD_RATE_BPS,
    FACTORY_BAUD_INDEX,
    H54_LAYOUT,
    HARDWARE_ERROR_BITS_MASK,
    INDIRECT_ADDRESS_BASE,
    INDIRECT_COUNT,
    INDIRECT_DATA_BASE,
    RETURN_DELAY_UNIT_S,
    Access,
    Area,
    ControlItem,
    ControlTableLayout,
)
from sim_backend.dynamixel.protocol import ALERT_BIT, ErrorCode, Instruction
from sim_backend.servo import WriteCounter

if TYPE_CHECKING:
    from sim_backend.servo import Measurements

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

FACTORY_RESET_ALL = 0xFF
FACTORY_RESET_ALL_BUT_ID = 0x01
FACTORY_RESET_ALL_BUT_ID_AND_BAUD = 0x02

_TORQUE_ENABLE = "Torque Enable"
_INDIRECT_DATA_END = INDIRECT_DATA_BASE + INDIRECT_COUNT
_INDIRECT_ADDRESS_END = INDIRECT_ADDRESS_BASE + 2 * INDIRECT_COUNT


class H54Device:
    """One H54-200-S500-R: a bytearray control table plus the firmware's rules.

    `eeprom_overrides` sets EEPROM items (by e-Manual name) as this unit was configured, e.g.
    {"Return Delay Time": 0, "Max Position Limit": 100_000}; read-only identity items such as
    "Model Number" may be overridden too (to emulate another model). A factory reset returns the
    writable ones to the e-Manual values.
    """

    def __init__(
        self,
        dxl_id: int = 1,
        *,
        baud_index: int = FACTORY_BAUD_INDEX,
        firmware_version: int = DEFAULT_FIRMWARE_VERSION,
        eeprom_overrides: Mapping[str, int] | None = None,
        reboot_time_s: float = DEFAULT_REBOOT_TIME_S,
        layout: ControlTableLayout = H54_LAYOUT,
    ) -> None:
        if reboot_time_s < 0:
            raise ValueError(f"reboot_time_s must be >= 0, got {reboot_time_s}")
        self._layout = layout
        self._table = bytearray(layout.size_bytes)
        self.reboot_time_s = reboot_time_s
        self.silenced = False  # firmware-side fault: the device hears nothing, answers nothing
        self._reboot_until_s = float("-inf")
        self._in_shutdown = False
        self._registered: tuple[int, bytes] | None = None
        self._reboot_listeners: list[Callable[[], None]] = []
        self._indirect_map: list[int] | None = None  # Indirect Address 1..256, cached
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
        self._direct_items: dict[str, tuple[int, int, int, bool]] = {
            item.name: (item.address, item.end, item.size, item.signed)
            for item in layout.items
            if not (INDIRECT_DATA_BASE <= item.address < _INDIRECT_DATA_END)
            and not (item.end > INDIRECT_ADDRESS_BASE and item.address < _INDIRECT_ADDRESS_END)
        }
        # Plain items by (address, size): a write of exactly one of them takes a short path.
        self._whole_items: dict[tuple[int, int], ControlItem] = {
            (item.address, item.size): item
            for item in layout.items
            if item.name in self._direct_items
        }
        self._measured_names = frozenset(item.name for item in layout.items if item.measured)
        self._measurement_address, self._measurement_packer = _packer(
            [self._direct_items[name] for name in _MEASUREMENT_ITEMS], layout
        )
        # Each checked item's Data Limit bounds (e-Manual): a constant, or another plain item
        # read straight from the table (address, end, signed, negated)
        self._limit_bounds: dict[str, tuple[_Bound, _Bound]] = {
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
        return BAUD_RATE_BPS[self._table[8]]

    @property
    def return_delay_s(self) -> float:
        """Return Delay Time (9) in seconds (2 us per unit)."""
        return self._table[9] * RETURN_DELAY_UNIT_S

    @property
    def status_return_level(self) -> int:
        return self._table[891]

    @property
    def torque_enabled(self) -> bool:
        return self._table[562] != 0

    @property
    def in_shutdown(self) -> bool:
        """True after a hardware error enabled in Shutdown (48) until the next REBOOT."""
        return self._in_shutdown

    @property
    def hardware_error_status(self) -> int:
        return self._table[892]

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
        if INDIRECT_DATA_BASE <= item.address < _INDIRECT_DATA_END:
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
        if INDIRECT_DATA_BASE <= item.address < _INDIRECT_DATA_END:
            self._table[self._indirect_target(item.address)] = item.encode(value)[0]
        else:
            self._store(item, value)

    def set_measurements(self, measurements: Measurements) -> None:
        """Firmware-side: the Present* items after a physics step, in one go (the revision
        stays: they are not the firmware's inputs)."""
        # in the order of _MEASUREMENT_ITEMS, one pack over the block (gaps: undefined bytes)
        self._measurement_packer.pack_into(self._table, self._measurement_address, *measurements)

    def attach_measurement_source(self, write_measurements: Callable[[], None]) -> None:
        """`write_measurements()` runs before every read that may cover the Present* items (a
        READ, SYNC_READ or BULK_READ, Indirect Data, `item` of a measured item): the firmware
        writes them then with `set_measurements`, if they changed since."""
        self._measurement_source = write_measurements

    def raise_hardware_error(self, bits: int) -> None:
        """OR `bits` into Hardware Error Status (892). Bits also set in Shutdown (48) turn
        torque off and latch the shutdown until REBOOT."""
        if bits & ~HARDWARE_ERROR_BITS_MASK or bits < 0:
            raise ValueError(
                f"hardware error bits must be within 0x{HARDWARE_ERROR_BITS_MASK:02X} "
                f"(bits 7 and 6 are unused), got 0x{bits:X}"
            )
        self._bump()
        self._table[892] |= bits
        if bits & self.item("Shutdown"):
            self._table[562] = 0
            self._in_shutdown = True

    def clear_hardware_error(self, bits: int) -> None:
        """Clear bits of Hardware Error Status (a non-latched condition went away). The
        shutdown latch stays: only REBOOT clears it."""
        self._bump()
        self._table[892] &= ~bits & 0xFF

    def available(self, now_s: float) -> bool:
        """False while rebooting or while silenced by a firmware-side fault."""
        return not self.silenced and now_s >= self._reboot_until_s

    def add_reboot_listener(self, fn: Callable[[], None]) -> None:
        """`fn()` runs after every REBOOT / FACTORY_RESET (RAM is back to initial values)."""
        self._reboot_listeners.append(fn)

    # ---------------------------------------------------------------- protocol face

    def replies_to(self, instruction: int) -> bool:
        """Status Return Level (891): 0 = PING only, 1 = PING and READ, 2 = everything.
        SYNC_READ and BULK_READ count as READ."""
        if instruction == Instruction.PING:
            return True
        level = self.status_return_level
        if level >= 2:
            return True
        return level == 1 and instruction in (
            Instruction.READ,
            Instruction.SYNC_READ,
            Instruction.BULK_READ,
        )

    def status_error(self, error: int) -> int:
        """The status packet's error byte: `error` plus the alert bit while HES != 0."""
        return error | ALERT_BIT if self._table[892] else error

    def ping(self) -> bytes:
        """PING status params: model number LSB, MSB, firmware version."""
        return bytes((self._table[0], self._table[1], self._table[6]))

    def read(self, address: int, length: int) -> tuple[int, bytes]:
        """READ: (error number, data). Undefined bytes inside the table read as 0."""
        if address < 0 or length < 0 or address + length > self._layout.size_bytes:
            return ErrorCode.ACCESS, b""
        if self._measurement_source is not None:
            self._measurement_source()
        end = address + length
        table = self._table
        if end <= INDIRECT_DATA_BASE or address >= _INDIRECT_DATA_END:
            return ErrorCode.NONE, bytes(table[address:end])
        data = bytearray(table[address:end])
        targets = self._indirect_targets()
        for data_address in range(max(address, INDIRECT_DATA_BASE), min(end, _INDIRECT_DATA_END)):
            data[data_address - address] = table[targets[data_address - INDIRECT_DATA_BASE]]
        return ErrorCode.NONE, bytes(data)

    def write(self, address: int, data: bytes) -> int:
        """WRITE: all of it or none of it; returns the error number."""
        whole_item = self._whole_items.get((address, len(data)))
        if whole_item is not None:
            return self._write_whole_item(whole_item, bytes(data))
        error, plan = self._plan_write(address, data)
        if error == ErrorCode.NONE:
            self._bump()
            for physical, byte in plan:
                self._table[physical] = byte
                if INDIRECT_ADDRESS_BASE <= physical < _INDIRECT_ADDRESS_END:
                    self._indirect_map = None
        return error

    def write_item(self, name: str, value: int) -> int:
        """WRITE of one item by name, under every rule a WRITE packet meets; the error number."""
        item = self._layout[name]
        return self.write(item.address, item.encode(value))

    def reg_write(self, address: int, data: bytes) -> int:
        """REG_WRITE: check now, register for ACTION, Registered Instruction := 1."""
        error, _ = self._plan_write(address, data)
        if error == ErrorCode.NONE:
            self._registered = (address, bytes(data))
            self._table[890] = 1
        return error

    def action(self) -> int:
        """ACTION: run the registered write; Registered Instruction := 0."""
        if self._registered is None:
            return ErrorCode.INSTRUCTION
        address, data = self._registered
        self._registered = None
        self._table[890] = 0
        return self.write(address, data)

    def reboot(self, now_s: float) -> None:
        """REBOOT after the status went out: RAM to initial values, silent for a while."""
        for item in self._layout.items:
            if item.area is Area.RAM and not item.measured:
                self._store(item, item.default)
        self._goal_from_present()
        self._registered = None
        self._in_shutdown = False
        self._reboot_until_s = now_s + self.reboot_time_s
        for listener in self._reboot_listeners:
            listener()

    def check_factory_reset(self, option: int) -> int:
        """Error number FACTORY_RESET with `option` would get (NONE: it will run)."""
        valid = (FACTORY_RESET_ALL, FACTORY_RESET_ALL_BUT_ID, FACTORY_RESET_ALL_BUT_ID_AND_BAUD)
        if option not in valid:
            return ErrorCode.DATA_RANGE
        if self.torque_enabled:
            return ErrorCode.ACCESS
        return ErrorCode.NONE

    def factory_reset(self, option: int, now_s: float) -> None:
        """FACTORY_RESET (after `check_factory_reset` said yes and the status went out)."""
        keep = {
            FACTORY_RESET_ALL_BUT_ID: {"ID"},
            FACTORY_RESET_ALL_BUT_ID_AND_BAUD: {"ID", "Baud Rate"},
        }.get(option, set())
        for item in self._layout.items:
            writable_eeprom = item.area is Area.EEPROM and item.access is Access.READ_WRITE
            if writable_eeprom and item.name not in keep:
                self._store(item, item.default)
        self.reboot(now_s)

    # ---------------------------------------------------------------- internals

    def _store(self, item: ControlItem, value: int) -> None:
        self._bump()
        self._table[item.address : item.end] = item.encode(value)
        if item.end > INDIRECT_ADDRESS_BASE and item.address < _INDIRECT_ADDRESS_END:
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
        """Indirect Address 1..256 as a list (rebuilt after any write to 49..560)."""
        if self._indirect_map is None:
            table = self._table
            self._indirect_map = [
                table[base] | (table[base + 1] << 8)
                for base in range(INDIRECT_ADDRESS_BASE, _INDIRECT_ADDRESS_END, 2)
            ]
        return self._indirect_map

    def _indirect_target(self, data_address: int) -> int:
        return self._indirect_targets()[data_address - INDIRECT_DATA_BASE]

    def _physical(self, address: int) -> int:
        """Where the byte at `address` really lives (Indirect Data follows its map)."""
        if INDIRECT_DATA_BASE <= address < _INDIRECT_DATA_END:
            return self._indirect_target(address)
        return address

    def _bound(self, bound: str | int | None) -> _Bound:
        """A Data Limit bound as `_limit_value` reads it: None, a constant, or (address, end,
        signed, negated) of the plain item it names."""
        if bound is None or isinstance(bound, int):
            return bound
        name = bound.removeprefix("-")
        address, end, _, signed = self._direct_items[name]
        return (address, end, signed, bound.startswith("-"))

    def _limit_value(self, bound: _Bound) -> int | None:
        if bound is None or isinstance(bound, int):
            return bound
        address, end, signed, negated = bound
        value = int.from_bytes(self._table[address:end], "little", signed=signed)
        return -value if negated else value

    def _refused(self, item: ControlItem | None, torque_on: bool) -> bool:
        """Access Error for a write to this item: none there, read-only, EEPROM while torque is
        on, or its gate closed."""
        if item is None or item.access is Access.READ:
            return True
        if item.area is Area.EEPROM and torque_on:
            return True
        if item.writable_when is not None:
            gate_name, gate_value = item.writable_when
            if self.item(gate_name) != gate_value:
                return True
        return False

    def _value_error(self, values: list[tuple[ControlItem, int]]) -> int:
        """Range, then limit, then shutdown errors of the values a write would store."""
        for item, value in values:
            if not item.in_range(value):
                return ErrorCode.DATA_RANGE
        for item, value in values:
            bounds = self._limit_bounds.get(item.name)
            if bounds is None:
                continue
            if item.address == self._goal_position_address and (
                self._table[self._operating_mode_address] == 4
            ):
                continue  # Extended Position Control Mode ignores the position limits
            low = self._limit_value(bounds[0])
            high = self._limit_value(bounds[1])
            if (low is not None and value < low) or (high is not None and value > high):
                return ErrorCode.DATA_LIMIT
        for item, value in values:
            if item.name == _TORQUE_ENABLE and value == 1 and self._in_shutdown:
                return ErrorCode.RESULT_FAIL
        return ErrorCode.NONE

    def _write_whole_item(self, item: ControlItem, data: bytes) -> int:
        """WRITE of exactly one plain item (the host's Goal Position every tick): the checks
        of `_plan_write` for that item, without walking it byte by byte."""
        if self._refused(item, self.torque_enabled):
            return ErrorCode.ACCESS
        error = self._value_error([(item, item.decode(data))])
        if error == ErrorCode.NONE:
            self._bump()
            self.goal_position_writes += item.address == self._goal_position_address
            self._table[item.address : item.end] = data
        return error

    def _plan_write(self, address: int, data: bytes) -> tuple[int, list[tuple[int, int]]]:
        """Check a write of `data` at `address`; return (error, [(physical address, byte)])."""
        layout = self._layout
        if not data:
            return ErrorCode.DATA_LENGTH, []
        if address < 0 or address + len(data) > layout.size_bytes:
            return ErrorCode.ACCESS, []
        torque_on = self.torque_enabled
        plan: list[tuple[int, int]] = []
        touched: dict[str, tuple[ControlItem, dict[int, int]]] = {}
        for offset, byte in enumerate(data):
            physical = self._physical(address + offset)
            item = layout.item_at(physical)
            if self._refused(item, torque_on):
                return ErrorCode.ACCESS, []
            assert item is not None
            touched.setdefault(item.name, (item, {}))[1][physical - item.address] = byte
            plan.append((physical, byte))
        values: list[tuple[ControlItem, int]] = []
        for item, item_bytes in touched.values():
            if len(item_bytes) != item.size:
                return ErrorCode.DATA_LENGTH, []
            raw = bytes(item_bytes[k] for k in range(item.size))
            values.append((item, item.decode(raw)))
        error = self._value_error(values)
        return error, plan if error == ErrorCode.NONE else []


_Bound = int | tuple[int, int, bool, bool] | None


def _packer(
    slots: list[tuple[int, int, int, bool]], layout: ControlTableLayout
) -> tuple[int, struct.Struct]:
    """(first address, little-endian Struct) writing items (address, end, size, signed) in
    address order with one pack_into; the gaps between them must be undefined bytes (which
    always read 0, and the pad bytes write 0)."""
    codes = {1: "b", 2: "h", 4: "i"}
    fmt = "<"
    end = slots[0][0]
    for address, item_end, size, signed in slots:
        gap = range(end, address)
        if address < end or any(layout.item_at(byte) is not None for byte in gap):
            raise ValueError("the measured items must follow each other, gaps undefined")
        fmt += "x" * len(gap) + (codes[size] if signed else codes[size].upper())
        end = item_end
    return slots[0][0], struct.Struct(fmt)
