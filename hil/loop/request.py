"""What a run is asked to do (`RunRequest`), and how Ctrl-C / SIGTERM reach it (`StopFlag`)."""

from __future__ import annotations

import math
import signal
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hil.experiments import Experiment
from hil.output.channels import MessageSink
from hil.vocabulary import ControllerChoice

# The longest run `hil run` and a sweep accept: a day. A run's memory does not grow with its
# length (the loop computes its reference in chunks), but its record does, ~19 GB a day for
# the testbed with run.mcap (hil.output.rundir.estimated_record_bytes). A longer trial is
# several runs.
MAX_RUN_DURATION_S = 24 * 3600.0


def duration_problem(duration_s: float) -> str | None:
    """Why a run cannot last `duration_s` (None: it can): what `hil run --duration` and a
    sweep's `duration_s` are judged by before anything starts."""
    if not (math.isfinite(duration_s) and duration_s > 0):
        return f"must be a finite time > 0 s, got {duration_s}"
    if duration_s > MAX_RUN_DURATION_S:
        return (
            f"{duration_s:g} s is longer than a run may be ({MAX_RUN_DURATION_S:g} s, a day: "
            "the testbed's record alone grows ~19 GB a day); make it several runs"
        )
    return None


@dataclass(frozen=True)
class RunRequest:
    experiment: Experiment
    choice: ControllerChoice
    out_dir: Path
    duration_s: float | None = None
    overruns: tuple[tuple[float, float], ...] = ()  # injected loop overruns (start, duration)
    reboot_first: bool = False
    on_event: Callable[[str], None] | None = None  # a line per safety event (stderr)
    on_progress: Callable[[float, float], None] | None = None  # (loop time, run duration)
    mcap: bool = True  # write run.mcap beside the CSV files
    sinks: tuple[MessageSink, ...] = ()  # more receivers of the log's messages (live view)

    @property
    def run_duration_s(self) -> float:
        return self.duration_s if self.duration_s is not None else self.experiment.duration_s


class StopFlag:
    """Set by SIGINT/SIGTERM; the loop checks it every tick and leaves through its `finally`.

    A session that runs several experiments installs one for all of them (`hil run` with no
    experiment stops the whole plan on Ctrl-C); `run_experiment` installs its own otherwise.
    """

    def __init__(self) -> None:
        self.reason: str | None = None
        self._previous: dict[int, Any] = {}

    def __call__(self, signum: int, _frame: object) -> None:
        self.reason = f"{signal.Signals(signum).name}"

    def install(self) -> None:
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._previous[sig] = signal.signal(sig, self)

    def restore(self) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
        self._previous.clear()
