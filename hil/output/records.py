"""What a run leaves behind for the report: its ending, metrics and safety events."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hil.vocabulary import ControllerChoice, RunEnding, SafetyEvent, Termination

# The metrics' key for those a run could not measure: {metric: why} (their values are None),
# e.g. a first peak looked for over 0.5 s after a push in a run that ended 25 ms after it.
UNMEASURED = "unmeasured"


@dataclass
class RunResult:
    """One run: where it wrote, how it ended, its metrics, what the supervisor did."""

    out_dir: Path
    ending: RunEnding
    metrics: dict[str, Any]
    safety_events: list[SafetyEvent] = field(default_factory=list)
    ticks: int = 0
    wall_time_s: float = 0.0
    exit_notes: tuple[str, ...] = ()  # what the exit path did (summary.json "exit")
    # on_exit asked for torque off and the actuators did not take it (a lost bus): they may
    # still hold their last goal with torque on
    torque_off_failed: bool = False

    @property
    def ok(self) -> bool:
        return self.ending.ok

    @property
    def termination(self) -> Termination:
        return self.ending.termination

    @property
    def exit_status(self) -> int:
        """What `hil run` exits with for this run: 0 completed, 1 a safety stop, a failure or an
        interrupt, 3 torque could not be turned off (hil/cli/exit_codes.py)."""
        if self.torque_off_failed:
            return 3
        return 0 if self.ok else 1


@dataclass(frozen=True)
class RunEntry:
    """One run of a comparison: which experiment, which controller, what came of it."""

    experiment: str
    choice: ControllerChoice
    result: RunResult
