"""Run directories: their names (built once), and reading one back (`load_run`)."""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any

import numpy as np

from hil.output.runlog import read_log
from hil.output.strict_json import dumps

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
    """About how many bytes a run of `ticks` ticks writes (see _RECORD_BYTES_PER_TICK)."""
    base, per_joint = _RECORD_BYTES_PER_TICK[mcap]
    return ticks * (base + per_joint * n_joints)


@dataclass(frozen=True)
class RunData:
    """What a run directory holds (see hil.output.runlog): log columns, meta, summary, events."""

    out_dir: Path
    columns: dict[str, np.ndarray]
    meta: dict[str, Any]
    summary: dict[str, Any]
    events: tuple[dict[str, Any], ...]
    joint_names: tuple[str, ...]  # ("",) for a single-joint log (no column suffixes)

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
    """Read a run directory written by hil.output.runlog.RunLog; only log.csv is required."""
    out_dir = Path(out_dir)
    log_path = out_dir / "log.csv"
    if not log_path.is_file():
        raise FileNotFoundError(f"{out_dir} holds no log.csv: is it a run directory?")
    columns = read_log(log_path)
    if "time_s" not in columns:
        raise ValueError(f"{log_path} has no time_s column: not a hil run log")
    suffixed = tuple(m.group(1) for c in columns if (m := _JOINT_COLUMN.match(c)))
    events: list[dict[str, Any]] = []
    events_path = out_dir / "events.jsonl"
    if events_path.is_file():
        events = [json.loads(line) for line in events_path.read_text().splitlines() if line]
    return RunData(
        out_dir=out_dir,
        columns=columns,
        meta=_read_json(out_dir / "meta.json"),
        summary=_read_json(out_dir / "summary.json", torn_ok=True),  # written last: may be torn
        events=tuple(events),
        joint_names=suffixed or ("",),
    )


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
    path = Path(out_dir) / "summary.json"
    summary = _read_json(path)
    summary[key] = value
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(dumps(summary, indent=2) + "\n")
    tmp.replace(path)
