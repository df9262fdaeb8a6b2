"""How a chain's per-tick transactions split when its models differ: one SYNC_READ per state
block geometry, one SYNC_WRITE per Goal Position address.

A sync instruction names one address and length for every device it lists. The state block
(`state_block.py`) reads at Indirect Data 1 (634) with the same 15-byte layout on every model of
the family, so any chain, mixed or not, reads its state in ONE sync read. Goal Position lies at
596 on the legacy PRO and at 564 on PRO+: a chain mixing the two layouts writes its goals in two
sync writes, one per address (its PRO models in one, its PRO+ models in the other); a chain of
one layout (any mix of H54/H42/M54/...) in one. Mapping Goal Position through indirect entries
would make it one write too, but through the indirect path of every device's firmware, where a
plain write of Goal Position is what ROBOTIS document and what the existing robots send: their
bytes on the wire stay as they were. Read-only chains on devices without the map read each
model's own RAM span (`DirectStateSpan`), one sync read per span geometry.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from dynamixel_sdk import GroupSyncRead

from drivers.dynamixel.control_table import ModelSpec
from drivers.dynamixel.state_block import DirectStateSpan, StateBlockLayout


@dataclass
class ReadGroup:
    """One SYNC_READ: the devices whose state block lies at the same address with the same
    size and byte layout.

    indices: their places in the chain (rows of the state arrays), in chain order.
    columns: where the decoded values go in a row of STATE_BLOCK_ITEMS (None: all, in order).
    reads_hardware_error: the block holds Hardware Error Status (else it is read on Alert).
    """

    indices: np.ndarray
    ids: tuple[int, ...]
    data_start: int
    size: int
    decoder: struct.Struct
    columns: np.ndarray | None
    reads_hardware_error: bool
    sync_read: GroupSyncRead | None = None

    @property
    def expected_length(self) -> int:
        """A reply's LEN field: INST + ERR + data + CRC(2)."""
        return self.size + 4


def read_groups(
    blocks: Sequence[StateBlockLayout | DirectStateSpan], ids: Sequence[int]
) -> list[ReadGroup]:
    """The sync reads of a chain whose device i reads `blocks[i]`, in order of first device."""
    keyed: dict[tuple[object, ...], list[int]] = {}
    for index, block in enumerate(blocks):
        direct = isinstance(block, DirectStateSpan)
        key = (block.data_start, block.size, block.decoder().format, direct, _columns(block))
        keyed.setdefault(key, []).append(index)
    groups = []
    for members in keyed.values():
        block = blocks[members[0]]
        direct = isinstance(block, DirectStateSpan)
        groups.append(
            ReadGroup(
                indices=np.array(members, dtype=np.intp),
                ids=tuple(ids[i] for i in members),
                data_start=block.data_start,
                size=block.size,
                decoder=block.decoder(),
                columns=np.array(block.columns, dtype=np.intp) if direct else None,
                reads_hardware_error=not direct or block.reads_hardware_error,
            )
        )
    return groups


def _columns(block: StateBlockLayout | DirectStateSpan) -> tuple[int, ...]:
    return block.columns if isinstance(block, DirectStateSpan) else ()


@dataclass
class WriteGroup:
    """One SYNC_WRITE of Goal Position: the devices that hold it at `address`.

    params: [ID, 4 bytes of Goal Position] per device, built once; each tick changes only the
    goal bytes."""

    address: int
    indices: np.ndarray
    params: np.ndarray


def write_groups(specs: Sequence[ModelSpec], ids: Sequence[int]) -> list[WriteGroup]:
    """The Goal Position sync writes of a chain whose device i is of model `specs[i]`."""
    keyed: dict[int, list[int]] = {}
    for index, spec in enumerate(specs):
        keyed.setdefault(spec.item("Goal Position").address, []).append(index)
    groups = []
    for address, members in keyed.items():
        params = np.zeros((len(members), 5), dtype=np.uint8)
        params[:, 0] = [ids[i] for i in members]
        groups.append(WriteGroup(address, np.array(members, dtype=np.intp), params))
    return groups
