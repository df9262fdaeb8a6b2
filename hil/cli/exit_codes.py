"""The exit status of every `hil` command (README, "Exit status")."""

from __future__ import annotations

import enum


class ExitCode(enum.IntEnum):
    OK = 0  # the run completed / the command did what it was asked
    FAILED = 1  # a safety stop, a failure, an interruption
    USAGE = 2  # bad arguments or configuration: nothing was sent to any device
    # the run asked for torque off at its end and the actuators did not take it (a lost bus):
    # they may still hold their last goal with torque on - cut their power
    TORQUE_NOT_OFF = 3
