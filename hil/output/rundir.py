"""Run directories: their names (built once), and reading one back (`load_run`)."""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any

import numpy as np

from hil.output.record_files import RESERVE_BYTES
from hil.output.runlog import read_log_checked, write_summary_file

_JOINT_COLUMN = re.compile(r"^link_angle_rad\[(.+)\]$")


def timestamp() -> str:
    """The prefix of run directory names: 20261201-154213."""
    return datetime.now().strftime("%Y%m%d-%H%M%S")


def unique_dir(path: Path) -> Path:
    """`path`, or `path-2`, `path-3`, ... whichever does not exist yet (not created: for a run
    directory use `create_run_dir`, which two processes cannot both get)."""
    candidate, n = path, 1
    while candidate.exists():
        n += 1
        candidate = path.with_name(f"{path.name}-{n}")
    return candidate


def create_run_dir(root: Path, name: str) -> Path:
    """A new, empty directory `root/name` (or `name-2`, `name-3`, ...), created exclusively:
    `mkdir` without exist_ok either creates it or fails, so two runs started in the same second
    into the same root never share one, whatever the clock says."""
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    n = 1
    while True:
        candidate = root / (name if n == 1 else f"{name}-{n}")
        try:
            candidate.mkdir()
        except FileExistsError:
            n += 1
            continue
        return candidate


# What a run's record takes per tick (log.csv + timing.csv, and run.mcap), measured on 2 s
# in-process runs: the testbed (1 joint, a force sensor) 192 B without run.mcap, 1095 B with
# it; DYROS-JET's legs (12 joints, two foot sensors) 1563 B and 4795 B. A line through the two.
# With the robot's frames in run.mcap (hil/output/robot_view.py; 2 s impact and stand runs of
# `hil run`): 1239 B and 5959 B.
_RECORD_BYTES_PER_TICK = {False: (67.0, 125.0), True: (810.0, 429.0)}  # (base, per joint)


def estimated_record_bytes(ticks: int, n_joints: int, mcap: bool) -> float:
    """About how many bytes a run of `ticks` ticks writes (see _RECORD_BYTES_PER_TICK), and the
    room kept for the record's end (hil/output/record_files.py)."""
    base, per_joint = _RECORD_BYTES_PER_TICK[mcap]
    return ticks * (base + per_joint * n_joints) + RESERVE_BYTES


def describe_bytes(count: float) -> str:
    """A size in the unit that fits it: 950 B, 12 kB, 3.4 MB, 19.2 GB (SI: 1 kB = 1000 B)."""
    for unit, size in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if count >= size:
            value = count / size
            return f"{value:.0f} {unit}" if value >= 100 else f"{value:.1f} {unit}"
    return f"{count:.0f} B"


@dataclass(frozen=True)
class RunData:
    """What a run directory holds (see hil.output.runlog): log columns, meta, summary, events."""

    out_dir: Path
    columns: dict[str, np.ndarray]
    meta: dict[str, Any]
    summary: dict[str, Any]
    events: tuple[dict[str, Any], ...]
    joint_names: tuple[str, ...]  # ("",) for a single-joint log (no column suffixes)
    # what was read around: a torn last row of log.csv, a torn last line of events.jsonl
    notes: tuple[str, ...] = ()

    @property
    def time_s(self) -> np.ndarray:
        return self.columns["time_s"]

    def signal(self, name: str, joint: str = "") -> np.ndarray:
        """A per-joint column: `name` for a single-joint log, `name[joint]` otherwise."""
        key = f"{name}[{joint}]" if joint else name
        try:
            return self.columns[key]
        except KeyError:
            raise KeyError(f"{self.out_dir / 'log.csv'} has no column {key!r}") from None

    def per_joint(self, name: str) -> list[np.ndarray]:
        """A per-joint column for every joint, in joint order."""
        return [self.signal(name, joint) for joint in self.joint_names]

    @property
    def label(self) -> str:
        return str(self.meta.get("controller_label") or self.meta.get("controller", "?"))

    @property
    def termination(self) -> str:
        return str(self.summary.get("termination", "unknown (no summary.json)"))

    @property
    def experiment_start_s(self) -> float:
        """Loop time at which the experiment's own timeline began (after any re-homing)."""
        return float(self.summary.get("experiment_start_s") or 0.0)


def load_run(out_dir: Path) -> RunData:
    """Read a run directory written by hil.output.runlog.RunLog; only log.csv is required.
    A record cut off in the middle of its last line (a run killed, or written before the
    record kept its lines whole) is read without that line, and `notes` says so."""
    out_dir = Path(out_dir)
    log_path = out_dir / "log.csv"
    if not log_path.is_file():
        raise FileNotFoundError(f"{out_dir} holds no log.csv: is it a run directory?")
    columns, torn = read_log_checked(log_path)
    if "time_s" not in columns:
        raise ValueError(f"{log_path} has no time_s column: not a hil run log")
    notes = [torn] if torn else []
    suffixed = tuple(m.group(1) for c in columns if (m := _JOINT_COLUMN.match(c)))
    events: list[dict[str, Any]] = []
    events_path = out_dir / "events.jsonl"
    if events_path.is_file():
        events, torn_event = _read_events(events_path)
        notes += [torn_event] if torn_event else []
    return RunData(
        out_dir=out_dir,
        columns=columns,
        meta=_read_json(out_dir / "meta.json"),
        summary=_read_json(out_dir / "summary.json", torn_ok=True),  # written last: may be torn
        events=tuple(events),
        joint_names=suffixed or ("",),
        notes=tuple(notes),
    )


def _read_events(path: Path) -> tuple[list[dict[str, Any]], str | None]:
    """events.jsonl's lines; a last line cut off is left out (and said)."""
    text = path.read_text()
    lines = text.splitlines()
    note = None
    if lines and not text.endswith("\n"):
        try:
            json.loads(lines[-1])
        except ValueError:
            lines.pop()
            note = f"{path}: its last line is torn (the file ends in the middle of it): left out"
    return [json.loads(line) for line in lines if line], note


def _read_json(path: Path, *, torn_ok: bool = False) -> dict[str, Any]:
    """A JSON file's object ({} if there is none; torn_ok: also if it is not whole JSON)."""
    if not path.is_file():
        return {}
    try:
        return json.loads(path.read_text())
    except ValueError:
        if torn_ok:
            return {}
        raise


def add_to_summary(out_dir: Path, key: str, value: Any) -> None:
    """One more entry in a finished run's summary.json (what was learnt after the run ended,
    e.g. from the emulator), written atomically."""
    summary = _read_json(Path(out_dir) / "summary.json")
    summary[key] = value
    write_summary_file(out_dir, summary)
