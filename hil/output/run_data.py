"""Runs you can load: a run directory as arrays per signal and per joint, and as one long table.

`load_run(path)` reads what `hil run` (or your own loop through `hil.open_robot`) wrote into a
run directory: log.csv's columns, meta.json (what ran), summary.json (how it ended, its
metrics), events.jsonl (what the supervisor did) and, on the humanoid, kinematics.csv (the ZMP,
CoM and pelvis tilt per tick: hil/output/series.py). Only log.csv is required: a run without
summary.json (it did not finish writing its record) or with a torn one loads, and
`Run.summary_problem` says so.

log.csv names a joint's columns `signal[joint]` when the robot has several joints and `signal`
alone when it has one; `Run.signal(name, joint=...)` reads either the same way, so the same code
reads the testbed and the humanoid:

    >>> run = load_run(path)   # path: a run directory, e.g. "runs/20261203-115855-contact-pid"
    >>> run.experiment, run.controller, run.joints
    ('contact', 'pid', ('testbed',))
    >>> link = run.signal("link_angle_rad")            # one joint: no need to name it
    >>> link.shape == run.time_s.shape
    True
    >>> table = run.long()                             # one row per tick and joint (tidy)
    >>> table.names[:4]
    ('tick', 'time_s', 'joint', 'reference_rad')

and on DYROS-JET's legs (12 joints), e.g. `run.signal("link_angle_rad", joint="L_HipYaw")`,
`run.joint_signals("deflection_rad")` (ticks x 12) and `run.kinematics["zmp_y_m"]`.

The long table is tidy data as pandas users know it: one row per (tick, joint), one column per
signal (the run-wide columns, such as `phase` or `contact_force_n`, repeated on each joint's
row). `Table.to_pandas()` makes it a `pandas.DataFrame` (`pip install 'flexjoint-hil[analysis]'`);
without pandas it is a dict of numpy arrays (`Table.columns`) or a numpy structured array
(`Table.to_records()`).

Values are the log's: floats (NaN where a sensor gave nothing), `tick`, `skipped_ticks` and
`actuator_fault` integers, `torque_enabled`, `motor_valid` and `link_valid` booleans,
`supervisor_state` and `phase` strings.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from hil.output.channels import BOOL_COLUMNS, INTEGER_COLUMNS
from hil.output.rundir import RunData
from hil.output.rundir import load_run as read_run_dir
from hil.output.runlog import CLOCK_COLUMNS
from hil.output.series import KINEMATICS_FILE, read_series

if TYPE_CHECKING:
    import pandas

_INTEGERS = frozenset({"tick", "skipped_ticks", *INTEGER_COLUMNS})
_TEXT = frozenset({"supervisor_state", "phase"})
_NO_SUMMARY = "no summary.json: the run did not finish writing its record"
_TORN_SUMMARY = "summary.json is torn (not whole JSON)"


class NotARunDirectory(ValueError):
    """`load_run` was given a path that is not a run directory (the message says why)."""


class Table:
    """Columns of one length by name: a dict of numpy arrays (`columns`), with `to_pandas()`.

    >>> table = Table({"tick": np.arange(3), "joint": np.array(["a", "b", "c"])})
    >>> len(table), table.names, table["tick"].tolist()
    (3, ('tick', 'joint'), [0, 1, 2])
    >>> table.to_records()["joint"].tolist()
    ['a', 'b', 'c']
    """

    def __init__(self, columns: Mapping[str, np.ndarray]) -> None:
        self.columns = {name: np.asarray(values) for name, values in columns.items()}
        lengths = {name: len(values) for name, values in self.columns.items()}
        if len(set(lengths.values())) > 1:
            raise ValueError(f"a table's columns have one length; these have {lengths}")

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.columns)

    def __len__(self) -> int:
        return len(next(iter(self.columns.values()))) if self.columns else 0

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.columns[name]
        except KeyError:
            raise KeyError(f"no column {name!r}; the columns are {list(self.columns)}") from None

    def __contains__(self, name: object) -> bool:
        return name in self.columns

    def __iter__(self) -> Iterator[str]:
        return iter(self.columns)

    def __repr__(self) -> str:
        return f"Table({len(self)} rows: {', '.join(self.columns)})"

    def to_records(self) -> np.ndarray:
        """A numpy structured array, one field per column (text as fixed-width strings).

        >>> Table({"x": np.array([0.5, 1.5])}).to_records()["x"].tolist()
        [0.5, 1.5]
        """
        arrays = [
            values.astype(str) if values.dtype == object else values
            for values in self.columns.values()
        ]
        dtype = [(name, values.dtype) for name, values in zip(self.columns, arrays, strict=True)]
        records = np.empty(len(self), dtype=dtype)
        for name, values in zip(self.columns, arrays, strict=True):
            records[name] = values
        return records

    def to_pandas(self) -> pandas.DataFrame:
        """A `pandas.DataFrame` of these columns (pandas: the `analysis` extra).

        >>> frame = Table({"x": np.array([0.5, 1.5])}).to_pandas()   # doctest: +SKIP
        >>> frame["x"].mean()                                         # doctest: +SKIP
        1.0
        """
        try:
            import pandas
        except ImportError:
            raise ImportError(
                "Table.to_pandas() needs pandas: pip install 'flexjoint-hil[analysis]' (or use "
                "the table as it is: table.columns is a dict of numpy arrays, "
                "table.to_records() a numpy structured array)"
            ) from None
        return pandas.DataFrame(self.columns)


@dataclass(frozen=True)
class Run:
    """One run directory, loaded (`load_run`); see the module docstring.

    data             the reader's view (`hil.output.rundir.RunData`: the log's columns as
                     written, what the experiments' hooks take)
    joints           the joints' names, in log order (also for a one-joint log, whose columns
                     carry no name: from meta.json)
    summary_problem  None, or why summary.json is missing or unreadable
    kinematics       the humanoid's per-tick kinematics.csv as a `Table`, or None
    """

    data: RunData
    joints: tuple[str, ...]
    summary_problem: str | None
    kinematics: Table | None

    # --- what ran and how it ended --------------------------------------------------------
    @property
    def path(self) -> Path:
        return self.data.out_dir

    @property
    def meta(self) -> dict[str, Any]:
        """meta.json: the experiment, the controller and its parameters, the configuration,
        the seed, the versions."""
        return self.data.meta

    @property
    def summary(self) -> dict[str, Any]:
        """summary.json ({} when it is missing or torn: `summary_problem`)."""
        return self.data.summary

    @property
    def events(self) -> tuple[dict[str, Any], ...]:
        """events.jsonl: the supervisor's events and notices, one dict each."""
        return self.data.events

    @property
    def experiment(self) -> str:
        """The experiment's name ("contact", "stand", a plug-in's or your own loop's)."""
        return str(self.meta.get("experiment") or self.summary.get("experiment") or "")

    @property
    def controller(self) -> str:
        """The controller as the record labels it: 'gc+lqr+dob (Kdist 1)', 'PdGravity'.

        >>> load_run(path).controller
        'pid'
        """
        return self.data.label

    @property
    def metrics(self) -> dict[str, Any]:
        """The experiment's metrics from summary.json ({} without one)."""
        return dict(self.summary.get("metrics") or {})

    @property
    def termination(self) -> str:
        """How the run ended: 'completed', 'safety stop: current (back_off)', ...; without a
        readable summary.json, why not."""
        if self.summary_problem is not None:
            return f"unknown ({self.summary_problem})"
        return str(self.summary.get("termination", "unknown"))

    @property
    def completed(self) -> bool:
        """It ran to its end without a safety stop (a safety-stopped run did not complete)."""
        return self.termination == "completed"

    @property
    def safety_events(self) -> tuple[dict[str, Any], ...]:
        """The supervisor's reactions (cause, action, time_s, joint), first first."""
        return tuple(self.summary.get("safety_events") or ())

    # --- the log --------------------------------------------------------------------------
    @property
    def time_s(self) -> np.ndarray:
        """The loop's time of each row [s]."""
        return self.data.time_s

    @property
    def ticks(self) -> int:
        return int(self.time_s.size)

    @property
    def signals(self) -> tuple[str, ...]:
        """The per-joint signals the log holds, in log order (the measured ones, then the
        controller's terms).

        >>> load_run(path).signals[:3]
        ('reference_rad', 'goal_rad', 'motor_angle_rad')
        """
        names = self._joint_columns
        if self.data.joint_names == ("",):
            return tuple(names)
        joint = self.data.joint_names[0]
        suffix = f"[{joint}]"
        return tuple(name[: -len(suffix)] for name in names if name.endswith(suffix))

    @property
    def run_signals(self) -> tuple[str, ...]:
        """The log's columns that are not per joint: tick, time_s, the robot's sensors,
        supervisor_state, phase, skipped_ticks and the clock's."""
        joint = set(self._joint_columns)
        return tuple(name for name in self.data.columns if name not in joint)

    @property
    def _joint_columns(self) -> list[str]:
        """log.csv's per-joint block: after skipped_ticks, before the clock columns."""
        names = list(self.data.columns)
        start = names.index("skipped_ticks") + 1 if "skipped_ticks" in names else len(names)
        clock = [names.index(c) for c in CLOCK_COLUMNS if c in names]
        return names[start : min(clock, default=len(names))]

    def signal(self, name: str, joint: str | None = None) -> np.ndarray:
        """One signal over the run (one value per tick): a per-joint one of `joint` (which may
        be left out on a one-joint robot), or a run-wide one (`run_signals`) without a joint.

        >>> run = load_run(path)
        >>> float(run.signal("reference_rad")[0])
        0.0
        >>> run.signal("phase")[0]
        'hold'
        """
        if name in self.signals:
            return _typed(name, self.data.columns[self._column(name, joint)])
        if name in self.data.columns:
            if joint is not None:
                raise ValueError(f"{name} is not a per-joint signal: leave out joint=")
            return _typed(name, self.data.columns[name])
        raise KeyError(
            f"{self.path / 'log.csv'} has no signal {name!r}; per joint: {list(self.signals)}; "
            f"run-wide: {list(self.run_signals)}"
        )

    def joint_signals(self, name: str) -> np.ndarray:
        """A per-joint signal of every joint: ticks x joints, columns in `joints` order.

        >>> load_run(path).joint_signals("link_angle_rad").shape[1]
        1
        """
        return np.column_stack([self.signal(name, joint) for joint in self.joints])

    def _column(self, name: str, joint: str | None) -> str:
        if joint is None:
            if len(self.joints) > 1:
                raise ValueError(
                    f"{name}: the run has {len(self.joints)} joints: name one of "
                    f"{list(self.joints)} (or use joint_signals({name!r}) for all)"
                )
            joint = self.joints[0]
        if joint not in self.joints:
            raise KeyError(f"no joint {joint!r}; the run's joints are {list(self.joints)}")
        return name if self.data.joint_names == ("",) else f"{name}[{joint}]"

    def long(self) -> Table:
        """The whole log as one tidy table: a row per (tick, joint), tick-major; columns tick,
        time_s, joint, every per-joint signal, then the run-wide ones (module docstring).

        >>> run = load_run(path)
        >>> table = run.long()
        >>> len(table) == run.ticks * len(run.joints)
        True
        >>> table["joint"][0], float(table["link_angle_rad"][0])
        ('testbed', 0.0)
        """
        n = len(self.joints)
        columns: dict[str, np.ndarray] = {
            "tick": np.repeat(self.signal("tick"), n),
            "time_s": np.repeat(self.time_s, n),
            "joint": np.tile(np.array(self.joints, dtype=object), self.ticks),
        }
        for name in self.signals:
            columns[name] = self.joint_signals(name).reshape(-1)
        for name in self.run_signals:
            if name not in columns:
                columns[name] = np.repeat(self.signal(name), n)
        return Table(columns)


def load_run(path: str | os.PathLike[str]) -> Run:
    """A run directory, loaded: see the module docstring. Raises `NotARunDirectory` for a path
    that is not one (no log.csv, or a log.csv that is not a run's).

    >>> run = load_run(path)
    >>> run.termination
    'safety stop: current (back_off)'
    >>> run.completed, run.summary_problem is None
    (False, True)
    """
    directory = Path(path)
    if not directory.is_dir():
        raise NotARunDirectory(f"{directory}: no such directory")
    if not (directory / "log.csv").is_file():
        raise NotARunDirectory(f"{directory} is not a run directory: it holds no log.csv")
    try:
        data = read_run_dir(directory)
    except (ValueError, KeyError) as exc:  # JSONDecodeError is a ValueError
        raise NotARunDirectory(f"{directory} is not a readable run directory: {exc}") from None
    kinematics_path = directory / KINEMATICS_FILE
    kinematics = Table(read_series(kinematics_path)) if kinematics_path.is_file() else None
    return Run(data, _joints(data), _summary_problem(directory), kinematics)


def _joints(data: RunData) -> tuple[str, ...]:
    if data.joint_names != ("",):
        return data.joint_names
    named = (data.meta.get("bus") or {}).get("joints") or [
        joint.get("name") for joint in (data.meta.get("config") or {}).get("joint") or []
    ]
    return (str(named[0]),) if len(named) == 1 and named[0] else ("joint",)


def _summary_problem(directory: Path) -> str | None:
    path = directory / "summary.json"
    if not path.is_file():
        return _NO_SUMMARY
    try:
        json.loads(path.read_text())
    except ValueError:  # UnicodeDecodeError and JSONDecodeError are ValueErrors
        return _TORN_SUMMARY
    return None


def _typed(name: str, values: np.ndarray) -> np.ndarray:
    """A log column in its own type (module docstring); NaN keeps a flag or count a float."""
    if name in _TEXT or values.dtype == object:
        return values
    if not np.isfinite(values).all():
        return values
    if name in BOOL_COLUMNS:
        return values != 0
    if name in _INTEGERS:
        return values.astype(np.int64)
    return values
