"""The instruction semantics of an emulated PRO (`DynamixelProDevice`'s protocol face): what
PING, READ, WRITE, REG_WRITE, ACTION, REBOOT and FACTORY_RESET do to the control table, and the
checks a write meets. The addresses are the device's model's (legacy PRO or PRO+).

Rules (ROBOTIS e-Manual "Protocol 2.0" Status Packet/Instruction Details and the models' pages):
- EEPROM items are written only while Torque Enable = 0, else Access Error (7).
- Read-only or undefined addresses: Access Error (7). A READ may span undefined bytes of the
  table (they read as 0); a READ past the end of the table is an Access Error with no data.
- Data Length Error (5): a write that covers only part of an item (also through indirect data).
- Data Range Error (4): a value outside the item's range.
- Data Limit Error (6): Goal Position outside Min/Max Position Limit (PRO 36/40), Goal Velocity
  beyond +-Velocity Limit, Goal Torque beyond +-Torque Limit (PRO+: Goal Current, Current
  Limit; Goal PWM, PWM Limit), Goal Acceleration (PRO) / Profile Acceleration and Velocity
  (PRO+) outside 0..their limit.
- A write with any error changes nothing (all of it or none of it). Checks in this order:
  access, length, range, limit, shutdown.
- Alert bit 0x80 in every status packet while Hardware Error Status != 0.
- Shutdown (PRO 48, PRO+ 63): a hardware error whose bit is enabled there clears Torque Enable;
  only a REBOOT brings torque back ("REBOOT is the only method to reset Torque Enable to '1'").
  Not documented: the reply to Torque Enable = 1 while shut down. This emulator refuses it with
  Result Fail (1) (plus the alert bit) and leaves torque off.
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
  range and access (includes control_table_49_indirectdata_pro.md, p/control_table_168_indirect.md;
  PRO+: a target past the table's last item is an undefined byte). An Indirect Address that
  points at an Indirect Data byte reaches that byte's own storage (one level only: no loops).
"""

from __future__ import annotations

from sim_backend.dynamixel.control_table import Access, Area, ControlItem
from sim_backend.dynamixel.protocol import ALERT_BIT, ErrorCode, Instruction

FACTORY_RESET_ALL = 0xFF
FACTORY_RESET_ALL_BUT_ID = 0x01
FACTORY_RESET_ALL_BUT_ID_AND_BAUD = 0x02

_TORQUE_ENABLE = "Torque Enable"

# A Data Limit bound: None, a constant, or (address, end, signed, negated) of a plain item.
Bound = int | tuple[int, int, bool, bool] | None


class InstructionSemantics:
    """The protocol face of `DynamixelProDevice` (sim_backend/dynamixel/device.py), a mixin: it
    works on the device's control table, indirect map and latches."""

    def replies_to(self, instruction: int) -> bool:
        """Status Return Level (PRO 891, PRO+ 516): 0 = PING only, 1 = PING and READ,
        2 = everything. SYNC_READ and BULK_READ count as READ."""
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
        return error | ALERT_BIT if self._table[self._hardware_error_address] else error

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
        data_base, data_end = self._indirect.data_base, self._indirect.data_end
        if end <= data_base or address >= data_end:
            return ErrorCode.NONE, bytes(table[address:end])
        data = bytearray(table[address:end])
        targets = self._indirect_targets()
        for data_address in range(max(address, data_base), min(end, data_end)):
            data[data_address - address] = table[targets[data_address - data_base]]
        return ErrorCode.NONE, bytes(data)

    def write(self, address: int, data: bytes) -> int:
        """WRITE: all of it or none of it; returns the error number."""
        whole_item = self._whole_items.get((address, len(data)))
        if whole_item is not None:
            return self._write_whole_item(whole_item, bytes(data))
        error, plan = self._plan_write(address, data)
        if error == ErrorCode.NONE:
            self._bump()
            indirect = self._indirect
            for physical, byte in plan:
                self._table[physical] = byte
                if indirect.address_base <= physical < indirect.address_end:
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
            self._table[self._registered_address] = 1
        return error

    def action(self) -> int:
        """ACTION: run the registered write; Registered Instruction := 0."""
        if self._registered is None:
            return ErrorCode.INSTRUCTION
        address, data = self._registered
        self._registered = None
        self._table[self._registered_address] = 0
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

    def _bound(self, bound: str | int | None) -> Bound:
        """A Data Limit bound as `_limit_value` reads it: None, a constant, or (address, end,
        signed, negated) of the plain item it names."""
        if bound is None or isinstance(bound, int):
            return bound
        name = bound.removeprefix("-")
        address, end, _, signed = self._direct_items[name]
        return (address, end, signed, bound.startswith("-"))

    def _limit_value(self, bound: Bound) -> int | None:
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
                self._table[self._operating_mode_address] in self._goal_position_unlimited_modes
            ):
                continue  # e.g. Extended Position Control Mode ignores the position limits
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
