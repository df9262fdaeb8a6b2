"""Standard normals of one seeded Generator, handed out in order, drawn a block at a time.

numpy's Generator draws the same sequence of standard normals whether asked for one at a time
or for a block (`normal(0, s)` is `0 + s * z` with the next z), so a consumer that takes
`take(1)[0] * s` per draw gets the values one `normal(0, s)` call per draw would give, without
a Generator call per draw (tests/sim_backend/test_normal_stream.py checks it).
"""

from __future__ import annotations

import numpy as np

_NORMAL_BLOCK = 1024  # standard normals drawn per call to the Generator


class NormalStream:
    """See the module docstring."""

    def __init__(self, rng: np.random.Generator) -> None:
        self._rng = rng
        self._buffer = np.empty(0)
        self._values: list[float] | None = None  # the buffer as Python floats, for next()
        self._next = 0

    def take(self, count: int) -> np.ndarray:
        """The next `count` standard normals (a view: use it before the next call)."""
        end = self._next + count
        if end > len(self._buffer):
            rest = self._buffer[self._next :]
            self._buffer = np.concatenate((rest, self._rng.standard_normal(_NORMAL_BLOCK + count)))
            self._values = None
            self._next, end = 0, count
        drawn = self._buffer[self._next : end]
        self._next = end
        return drawn

    def next(self) -> float:
        """One standard normal as a Python float (from the block's Python floats: a node
        draws one per sample, and a numpy scalar per draw costs more than the draw)."""
        index = self._next
        values = self._values
        if values is None:
            values = self._values = self._buffer.tolist()
        if index >= len(values):
            return float(self.take(1)[0])
        self._next = index + 1
        return values[index]
