"""Fault knobs of an emulated Dynamixel line, set and cleared by scenario code.

The chain consults one `LineFaults` object on every instruction. They model what goes wrong
between the devices and the host, not inside a device (a device's own faults go through its
firmware face: `H54Device.raise_hardware_error`, `H54Device.silenced`).
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class FaultCounts:
    """How often each line fault actually fired (history: `LineFaults.clear` keeps it).

    replies_dropped: status packets lost (drop_reply_ids, drop_next_replies).
    replies_corrupted: status packets sent with a wrong CRC (corrupt_crc_ids, ...next_replies).
    instructions_unheard: instructions a device on `silent_ids` did not hear although they were
        for it (addressed to its ID, or broadcast); one per device and instruction.
    """

    replies_dropped: int = 0
    replies_corrupted: int = 0
    instructions_unheard: int = 0


@dataclass
class LineFaults:
    """What the line does to traffic right now.

    silent_ids: these IDs hear nothing and answer nothing, as if unplugged (their instructions are
        not executed; in a SYNC_READ/BULK_READ the devices listed after them stay silent too).
    drop_reply_ids: these IDs execute instructions but their status packets never reach the host
        (lost on the way: the devices after them in a SYNC_READ still answer).
    corrupt_crc_ids: status packets from these IDs arrive with a wrong CRC.
    drop_next_replies: the next N status packets (any ID) are lost; counts down.
    corrupt_next_replies: the next N status packets (any ID) get a wrong CRC; counts down.
    """

    silent_ids: set[int] = field(default_factory=set)
    drop_reply_ids: set[int] = field(default_factory=set)
    corrupt_crc_ids: set[int] = field(default_factory=set)
    drop_next_replies: int = 0
    corrupt_next_replies: int = 0
    fired: FaultCounts = field(default_factory=FaultCounts)

    def clear(self) -> None:
        """Back to a healthy line (`fired` keeps counting)."""
        self.silent_ids.clear()
        self.drop_reply_ids.clear()
        self.corrupt_crc_ids.clear()
        self.drop_next_replies = 0
        self.corrupt_next_replies = 0

    @property
    def replies_intact(self) -> bool:
        """No reply is to be dropped or corrupted (the usual line: nothing to consult)."""
        return not (
            self.drop_reply_ids
            or self.corrupt_crc_ids
            or self.drop_next_replies > 0
            or self.corrupt_next_replies > 0
        )

    def take_drop(self, dxl_id: int) -> bool:
        """Whether the reply from `dxl_id` is lost (consumes one `drop_next_replies`)."""
        if dxl_id in self.drop_reply_ids:
            self.fired.replies_dropped += 1
            return True
        if self.drop_next_replies > 0:
            self.drop_next_replies -= 1
            self.fired.replies_dropped += 1
            return True
        return False

    def take_corrupt(self, dxl_id: int) -> bool:
        """Whether the reply from `dxl_id` gets a bad CRC (consumes one `corrupt_next_replies`)."""
        if dxl_id in self.corrupt_crc_ids:
            self.fired.replies_corrupted += 1
            return True
        if self.corrupt_next_replies > 0:
            self.corrupt_next_replies -= 1
            self.fired.replies_corrupted += 1
            return True
        return False
