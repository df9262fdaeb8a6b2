"""The exit status of every `hil` command (README, "Exit status")."""

from __future__ import annotations

import enum


class ExitCode(enum.IntEnum):
    OK = 0  # the run completed / the command did what it was asked
    FAILED = 1  # a safety stop, a failure, an interruption
    USAGE = 2  # bad arguments or configuration: nothing was sent to any device
