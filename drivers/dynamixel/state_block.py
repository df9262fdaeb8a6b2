"""The per-tick state block, gathered through indirect addressing into one contiguous read.

Why: `GroupSyncRead` discards each device's status error byte (and with it the Alert bit 0x80),
and the items the loop needs are scattered (Present Position 611 .. Hardware Error Status 892 on
the PRO). Indirect Address n (49 + 2(n-1) on the PRO, 168 + 2(n-1) on PRO+, 2 bytes, EEPROM)
holds the address of ONE byte that then reads at Indirect Data n (634 + (n-1) on every model); a
4-byte item takes 4 consecutive entries (e-Manual includes control_table_49_indirectdata_pro,
p/control_table_168_indirect; ROBOTIS-Framework packs its bulk reads the same way). So one
SYNC_READ of the Indirect Data span returns, per device of any model:

    Present Position (4) | Present Velocity (4) | Present Current (2) | Present Input Voltage (2)
    | Hardware Error Status (1) | Torque Enable (1) | Present Temperature (1)      = 15 bytes

and the hardware error status and torque state reach the caller every tick. The block's
address, size and layout are the same on every model, so a chain that mixes models still reads
its whole state in one SYNC_READ.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from drivers.dynamixel.control_table import ControlItem, ModelSpec

STATE_BLOCK_ITEMS: tuple[str, ...] = (
    "Present Position",
    "Present Velocity",
    "Present Current",
    "Present Input Voltage",
    "Hardware Error Status",
    "Torque Enable",
    "Present Temperature",
)

_STRUCT_CODES = {(1, False): "B", (1, True): "b", (2, False): "H", (2, True): "h"}
_STRUCT_CODES.update({(4, False): "I", (4, True): "i"})


@dataclass(frozen=True)
class StateBlockLayout:
    """Where the state block lives on one model and how its bytes decode.

    indirect_targets: the control-table address each Indirect Address entry must hold, in order
        (one entry per byte).
    """

    spec: ModelSpec
    first_index: int

    @property
    def items(self) -> tuple[ControlItem, ...]:
        return tuple(self.spec.item(name) for name in STATE_BLOCK_ITEMS)

    @property
    def size(self) -> int:
        return sum(item.size for item in self.items)

    @property
    def indirect_targets(self) -> tuple[int, ...]:
        return tuple(
            item.address + byte_index for item in self.items for byte_index in range(item.size)
        )

    @property
    def indirect_address_start(self) -> int:
        return self.spec.indirect_address_of(self.first_index)

    @property
    def indirect_address_bytes(self) -> bytes:
        """The Indirect Address entries as written to the device (2 bytes LE per entry)."""
        return b"".join(target.to_bytes(2, "little") for target in self.indirect_targets)

    @property
    def data_start(self) -> int:
        """Address of the first Indirect Data byte of the block (the sync-read start)."""
        return self.spec.indirect_data_of(self.first_index)

    @property
    def last_index(self) -> int:
        return self.first_index + self.size - 1

    def check_fits(self) -> None:
        """Raise ValueError if the block does not fit in the model's indirect entries."""
        low, high = self.spec.indirect_target_range
        if self.first_index < 1 or self.last_index > self.spec.indirect_count:
            raise ValueError(
                f"indirect_first_index must be in 1..{self.spec.indirect_count - self.size + 1} "
                f"on the {self.spec.model_name} (the state block needs {self.size} entries), got "
                f"{self.first_index}"
            )
        outside = [address for address in self.indirect_targets if not low <= address <= high]
        if outside:
            raise ValueError(f"indirect targets {outside} are outside {low}..{high}")

    def decoder(self) -> struct.Struct:
        """A `struct.Struct` that unpacks the block into the values of STATE_BLOCK_ITEMS."""
        codes = "".join(_STRUCT_CODES[(item.size, item.signed)] for item in self.items)
        return struct.Struct("<" + codes)


# The state items that sit in one contiguous stretch of RAM, from Torque Enable to Present
# Temperature: PRO 562..625 (Hardware Error Status, 892, lies far beyond it); PRO+ 512..594,
# which holds Hardware Error Status (518) too.
SPAN_FIRST, SPAN_LAST = "Torque Enable", "Present Temperature"


@dataclass(frozen=True)
class DirectStateSpan:
    """The state block read without the indirect map: one SYNC_READ of the contiguous span
    Torque Enable .. Present Temperature, for a chain opened read-only on devices that have no
    state-block map yet (writing the map is an EEPROM write). On the PRO, Hardware Error Status
    is outside the span: a device reports a latched error through the Alert bit of every status
    packet (e-Manual Protocol 2.0, "Status Packet"), and only then is it read on its own; on
    PRO+ the span holds it (`reads_hardware_error`)."""

    spec: ModelSpec

    @property
    def names(self) -> tuple[str, ...]:
        """The state items inside the span, in address order."""
        low = self.spec.item(SPAN_FIRST).address
        last = self.spec.item(SPAN_LAST)
        inside = [
            name
            for name in STATE_BLOCK_ITEMS
            if low <= self.spec.item(name).address < last.address + last.size
        ]
        return tuple(sorted(inside, key=lambda name: self.spec.item(name).address))

    @property
    def items(self) -> tuple[ControlItem, ...]:
        return tuple(self.spec.item(name) for name in self.names)

    @property
    def reads_hardware_error(self) -> bool:
        return "Hardware Error Status" in self.names

    @property
    def data_start(self) -> int:
        return min(item.address for item in self.items)

    @property
    def size(self) -> int:
        return max(item.address + item.size for item in self.items) - self.data_start

    @property
    def columns(self) -> tuple[int, ...]:
        """Where each decoded value goes in a row of STATE_BLOCK_ITEMS."""
        return tuple(STATE_BLOCK_ITEMS.index(name) for name in self.names)

    def decoder(self) -> struct.Struct:
        """Unpacks the span into the values of `names` (in that order: the items are placed by
        address with pad bytes between them)."""
        codes, cursor = "", self.data_start
        for item in self.items:
            codes += "x" * (item.address - cursor) + _STRUCT_CODES[(item.size, item.signed)]
            cursor = item.address + item.size
        return struct.Struct("<" + codes)
