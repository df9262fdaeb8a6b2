"""The emulator's ground truth, written beside the run: what no sensor of the robot reports
(the humanoid's pelvis pose in the world), one row per SYNC, for the viewers of a finished run
(the ROS 2 bag's /tf, `hil render`) to use instead of estimating it.

It is the emulator's own file, never read back by the loop: the drivers and the emulator
still meet only on the wire. A row is written when the plant has stepped for a SYNC (in
lock-step: the state the host's reading of that tick shows); `time_s` is the plant's time.
Buffered, closed when the emulator ends; an emulator killed outright loses its last rows.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

TRUTH_LOG_NAME = "emulator_truth.csv"


class TruthLog:
    """Rows of `columns`, each from `row()`, to `path` (nothing written if path is "")."""

    def __init__(
        self, path: str, columns: Sequence[str], row: Callable[[], Sequence[float]]
    ) -> None:
        self._row = row
        self._file = open(Path(path), "w", encoding="utf-8") if path and columns else None  # noqa: SIM115
        if self._file is not None:
            self._file.write(",".join(("sync", "time_s", *columns)) + "\n")

    def write(self, sync: int, time_s: float) -> None:
        if self._file is not None:
            cells = (repr(round(float(v), 9)) for v in self._row())
            self._file.write(f"{sync},{round(time_s, 9)!r},{','.join(cells)}\n")

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None
