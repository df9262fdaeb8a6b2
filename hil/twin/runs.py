"""The recorded runs a twin is fitted from and checked on: a run directory read back with what its
meta.json says it was (experiment, configuration, controller, seed), checked for what a replay
needs, with a clear error naming the directory.

A replay drives the twin with what the run sent: the goal column (NaN on a tick that sent
nothing: the device kept its goal) and the torque state (`torque_enabled` at tick k+1 says
whether torque was on over tick k), from the run's first tick. The experiment's world (the
block, the pushes) comes from the experiment named in meta.json, as the emulator built it for
the run.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hil.config import Config, ConfigError, config_from_record
from hil.experiments import Experiment
from hil.output.rundir import RunData, load_run
from hil.robots import get_experiment

# The per-joint signals a replay compares (the log's columns), with their SI unit and the
# factor to the unit the report gives.
SIGNALS: dict[str, tuple[str, float]] = {
    "motor_angle_rad": ("mrad", 1e3),
    "link_angle_rad": ("mrad", 1e3),
    "deflection_rad": ("mrad", 1e3),
    "motor_current_a": ("A", 1.0),
}
FORCE_SIGNAL = "contact_force_n"  # the testbed's force sensor [N]


class NotATwinRun(ValueError):
    """A directory the twin cannot use (the message names it and says what is missing)."""


@dataclass(frozen=True)
class RecordedRun:
    """One run directory, as a replay needs it."""

    run: RunData
    config: Config
    experiment: Experiment
    seed: int

    @property
    def out_dir(self) -> Path:
        return self.run.out_dir

    @property
    def name(self) -> str:
        return f"{self.run.out_dir.name}"

    @property
    def experiment_name(self) -> str:
        return self.experiment.name

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(self.config.joint_names)

    @property
    def ticks(self) -> int:
        return len(self.run.time_s)

    @property
    def period_s(self) -> float:
        return self.config.loop.period_s

    def goals(self) -> np.ndarray:
        """(ticks, joints) the goal written at each tick (NaN: nothing sent)."""
        return np.column_stack(self._per_joint("goal_rad"))

    def torque_on_over_tick(self) -> np.ndarray:
        """(ticks,) whether torque was on over tick k (every joint's at tick k+1; the last
        tick's torque state is the exit path's: off unless the run held)."""
        torque = np.column_stack(self._per_joint("torque_enabled")) > 0.5
        over = np.zeros(self.ticks, dtype=bool)
        over[:-1] = torque[1:].all(axis=1)
        return over

    def signal(self, name: str) -> np.ndarray:
        """(ticks, joints) a per-joint signal; the deflection is link - motor."""
        if name == "deflection_rad":
            return self.signal("link_angle_rad") - self.signal("motor_angle_rad")
        return np.column_stack(self._per_joint(name))

    def force(self) -> np.ndarray | None:
        """The contact force [N] of a run with a block (None without one)."""
        if self.experiment.world.obstacle is None or FORCE_SIGNAL not in self.run.columns:
            return None
        return np.asarray(self.run.columns[FORCE_SIGNAL], dtype=float)

    @property
    def experiment_duration_s(self) -> float | None:
        """How long its experiment was planned to run (`hil run --duration`): its rows in the
        `experiment` phase plus the hold's (hil/loop/timeline.py: the experiment's time starts
        with the hold). None: no such rows."""
        phase = self.run.columns.get("phase")
        if phase is None:
            return None
        rows = int(np.count_nonzero(np.asarray(phase) == "experiment"))
        return (rows + self.config.loop.stop_cycles) * self.period_s if rows else None

    @property
    def controller(self) -> dict[str, Any]:
        """What meta.json says of the controller (for the closed-loop replay)."""
        meta = self.run.meta
        return {
            key: meta.get(key)
            for key in ("controller", "controller_spec", "kdist", "reading", "gc_compliance")
        }

    @property
    def open_loop(self) -> bool:
        return bool(getattr(self.experiment, "open_loop", False))

    @property
    def validation_start_s(self) -> float | None:
        """Where an identification run's held-out sweep begins (loop time), else None."""
        value = (self.run.summary.get("metrics") or {}).get("validation_start_s")
        return float(value) if isinstance(value, int | float) and math.isfinite(value) else None

    def _per_joint(self, name: str) -> list[np.ndarray]:
        try:
            return [np.asarray(c, dtype=float) for c in self.run.per_joint(name)]
        except KeyError as exc:
            raise NotATwinRun(f"{self.out_dir}: {exc.args[0]}") from None


def first_torque_tick(run: RecordedRun) -> int:
    """The first tick a replay compares: the one after torque came on."""
    on = np.flatnonzero(run.torque_on_over_tick())
    return int(on[0]) + 1 if on.size else run.ticks


def judge_run(run: RecordedRun, problems: list[str]) -> None:
    """A run whose excitation the supervisor rewrote, or that did not complete, into problems."""
    coverage = (run.run.summary.get("metrics") or {}).get("excitation_coverage")
    if isinstance(coverage, int | float) and coverage < 1.0:
        problems.append(
            f"{run.out_dir}: the supervisor rewrote {100 * (1 - coverage):.1f} % of the "
            "excitation's goals (a limit or a safety hold)"
        )
    if run.run.termination != "completed":
        problems.append(f"{run.out_dir}: the run did not complete ({run.run.termination})")


def read_run(path: str | Path) -> RecordedRun:
    """One run directory, checked (NotATwinRun says what is wrong)."""
    path = Path(path)
    if not path.is_dir():
        raise NotATwinRun(f"{path}: no such directory")
    try:
        run = load_run(path)
    except (FileNotFoundError, ValueError) as exc:
        raise NotATwinRun(f"{path}: not a run directory: {exc}") from None
    meta = run.meta
    for key in ("experiment", "config", "clock"):
        if key not in meta:
            raise NotATwinRun(f"{path}: meta.json has no {key!r}: not a run `hil run` wrote")
    try:
        config = config_from_record(meta["config"])
    except ConfigError as exc:
        raise NotATwinRun(f"{path}: its recorded configuration is not valid: {exc}") from None
    try:
        experiment = get_experiment(str(meta["experiment"]))
    except ValueError as exc:
        raise NotATwinRun(f"{path}: {exc}") from None
    names = tuple(config.joint_names)
    logged = run.joint_names
    if (len(names) > 1 and tuple(logged) != names) or (len(names) == 1 and logged != ("",)):
        raise NotATwinRun(f"{path}: its log's joints {logged} are not its configuration's {names}")
    if len(run.time_s) < 2:
        raise NotATwinRun(f"{path}: its log has {len(run.time_s)} rows")
    steps = np.diff(run.time_s)
    period = config.loop.period_s
    if np.max(np.abs(steps - period)) > 1e-3 * period:
        raise NotATwinRun(
            f"{path}: its ticks are not one period ({period:g} s) apart (a wall-clock run that "
            "skipped ticks): a replay steps the twin one period per row"
        )
    seed = meta.get("seed")
    return RecordedRun(run, config, experiment, int(seed) if isinstance(seed, int) else 0)


def read_runs(paths: Sequence[str | Path]) -> list[RecordedRun]:
    """Several runs of one robot (the same joints and robot model), checked."""
    runs = [read_run(p) for p in paths]
    if not runs:
        raise NotATwinRun("no run directory given")
    first = runs[0]
    for run in runs[1:]:
        if run.joint_names != first.joint_names or (
            run.config.model.robot != first.config.model.robot
        ):
            raise NotATwinRun(
                f"{run.out_dir} and {first.out_dir} are not runs of one robot (joints "
                f"{run.joint_names} vs {first.joint_names})"
            )
    return runs
