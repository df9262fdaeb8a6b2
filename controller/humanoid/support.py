"""Which foot carries the robot: the support state the GC (6)-(7) and Sm (19) depend on."""

from __future__ import annotations

import enum


class SupportState(enum.Enum):
    """Left single support, right single support, or double support."""

    LEFT = "left"
    RIGHT = "right"
    DOUBLE = "double"

    @property
    def feet(self) -> tuple[int, ...]:
        """Indices of the feet in contact (0 left, 1 right)."""
        return {SupportState.LEFT: (0,), SupportState.RIGHT: (1,), SupportState.DOUBLE: (0, 1)}[
            self
        ]
