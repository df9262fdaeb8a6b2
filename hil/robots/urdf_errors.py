"""What pinocchio's URDF parser says: it writes its errors to file descriptor 2 itself, past
Python's sys.stderr, so a configuration check keeps them to name them in its own message."""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
from collections.abc import Callable, Iterator


@contextlib.contextmanager
def parser_messages() -> Iterator[Callable[[], list[str]]]:
    """File descriptor 2 goes to a temporary file for the block; yields what was written."""
    lines: list[str] = []
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile(mode="w+") as kept:
        os.dup2(kept.fileno(), 2)
        try:
            yield lambda: lines
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            kept.seek(0)
            lines += kept.read().splitlines()
