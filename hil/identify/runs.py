"""From run directories (`hil run identify`) to the fit's input, with clear errors.

An identification run is a run directory (hil/output) whose meta.json names the excitation
(`experiment_parameters`, written by hil/experiments/identify.py) and whose summary.json holds
the time the held-out sweep begins (`metrics.validation_start_s`) and the current limit the run
read from each actuator's Torque Limit (`current_limit_a`). `read_identification_run` checks
each of these and says what is missing; `validation_start_of` combines several runs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hil.identify.records import JointLog, LogFormatError
from hil.output.rundir import RunData, load_run

IDENTIFY_EXPERIMENT = "identify"


class NotAnIdentificationRun(ValueError):
    """The directory is not a run, or not one an identification can use (the message says
    what is missing and how to make one)."""


@dataclass(frozen=True)
class IdentificationRun:
    """One identification run: its directory and, per joint name ("" for a single joint), the
    fit's input, the held-out start (loop time) and the actuator's current limit (None: not
    known)."""

    run: RunData
    logs: dict[str, JointLog]
    validation_start_s: float | None
    current_limit_a: dict[str, float | None]
    excitation: dict[str, Any]

    @property
    def out_dir(self) -> Path:
        return self.run.out_dir


def read_identification_run(path: str | Path) -> IdentificationRun:
    """Read and check one run directory; NotAnIdentificationRun says what is wrong."""
    path = Path(path)
    if not path.is_dir():
        raise NotAnIdentificationRun(f"{path}: no such directory")
    try:
        run = load_run(path)
    except (FileNotFoundError, ValueError) as exc:
        raise NotAnIdentificationRun(f"{path}: not a run directory: {exc}") from None
    _check_identification(run)
    excitation = dict(run.meta["experiment_parameters"])
    metrics = run.summary.get("metrics") or {}
    validation = metrics.get("validation_start_s")
    limits = list(run.summary.get("current_limit_a") or [])
    logs: dict[str, JointLog] = {}
    current: dict[str, float | None] = {}
    for index, joint in enumerate(run.joint_names):
        source = f"{path}" + (f" [{joint}]" if joint else "")
        try:
            logs[joint] = JointLog.from_log_columns(run.columns, joint or None, source=source)
        except LogFormatError as exc:
            raise NotAnIdentificationRun(str(exc)) from None
        limit = limits[index] if index < len(limits) else None
        current[joint] = float(limit) if _finite(limit) else None
    return IdentificationRun(
        run,
        logs,
        float(validation) if _finite(validation) else None,
        current,
        excitation,
    )


def _check_identification(run: RunData) -> None:
    where = run.out_dir
    experiment = run.meta.get("experiment")
    if not run.meta:
        raise NotAnIdentificationRun(
            f"{where}: no meta.json, so nothing says it is an identification run (make one "
            "with `hil run identify`)"
        )
    if experiment != IDENTIFY_EXPERIMENT:
        raise NotAnIdentificationRun(
            f"{where}: a {experiment!r} run, not an identification run: the fit needs the "
            "link free and an excitation on the goal (make one with `hil run identify`)"
        )
    missing = []
    if "experiment_parameters" not in run.meta:
        missing.append("the excitation's parameters (meta.json experiment_parameters)")
    if not run.summary:
        missing.append("summary.json (the run did not finish writing)")
    if missing:
        raise NotAnIdentificationRun(f"{where}: an identification run without {'; '.join(missing)}")


def _finite(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def validation_start_of(runs: list[IdentificationRun]) -> float | None:
    """The held-out start all runs share (each one's log time), or None when they differ or
    a run has none (the fit then holds out the last part of each log instead)."""
    starts = {run.validation_start_s for run in runs}
    if len(starts) != 1:
        return None
    (start,) = starts
    if start is None:
        return None
    ends = [float(log.time_s[-1]) for run in runs for log in run.logs.values()]
    return start if all(start < end for end in ends) else None
