"""Where each of the paper's relations holds: checked at every point of a sweep from its rows.

At a point, the runs of all controllers form a small comparison, and each experiment checks
its relations on them exactly as the comparison report does (`Experiment.relations`). The
sweep adds one relation per LQR controller on an impact experiment: the closed loop is stable
after the push - the run ends without a safety stop and the motion dies out at least
STABLE_BEFORE_END_S before the run ends (an oscillation that does not decay never settles; one
that grows trips the deflection watch). That is the emulated counterpart of the sampled loop's
spectral radius below 1 (the closed-loop analysis of controller/composition.py).

A relation is identified across points by (experiment, claim); its fraction is the share of
the points at which it could be checked where it holds.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hil.experiments.impact import ImpactExperiment
from hil.output.records import RunEntry, RunResult
from hil.output.report import Relation, check, metric
from hil.robots import EXPERIMENTS
from hil.sweep.spec import parse_controller
from hil.sweep.task import FAILED
from hil.vocabulary import RunEnding, Termination

STABLE_BEFORE_END_S = 0.5


@dataclass(frozen=True)
class PointRelation:
    """One relation at one point."""

    point_id: str
    values: dict[str, Any]
    relation: Relation

    @property
    def key(self) -> tuple[str, str]:
        return (self.relation.experiment, self.relation.claim)


@dataclass(frozen=True)
class RelationFraction:
    experiment: str
    claim: str
    holds: int
    does_not_hold: int
    not_checked: int

    @property
    def checked(self) -> int:
        return self.holds + self.does_not_hold

    @property
    def fraction(self) -> float | None:
        return self.holds / self.checked if self.checked else None

    def record(self) -> dict[str, Any]:
        return {
            "experiment": self.experiment,
            "claim": self.claim,
            "holds": self.holds,
            "does_not_hold": self.does_not_hold,
            "not_checked": self.not_checked,
            "fraction": self.fraction,
        }


def entry_of(row: dict[str, Any]) -> RunEntry:
    """A results.csv row as the comparison's RunEntry (a failed run: Termination.ERROR)."""
    ending = str(row["ending"])
    termination = Termination.ERROR if ending == FAILED else Termination(ending)
    result = RunResult(
        Path(str(row.get("out_dir") or ".")),
        RunEnding(termination, str(row.get("error") or "")),
        dict(row.get("metrics") or {}),
    )
    return RunEntry(str(row["experiment"]), parse_controller(str(row["controller"])), result)


def stability_relations(
    experiment: str, entries: Sequence[RunEntry], duration_s: float | None = None
) -> list[Relation]:
    """The closed loop stable after the push, for each LQR controller (module docstring);
    duration_s: the runs' duration when the sweep shortened them."""
    impact = EXPERIMENTS[experiment]
    if not isinstance(impact, ImpactExperiment) or not impact.world.pushes:
        return []
    after_push = (duration_s or impact.duration_s) - impact.world.pushes[0].start_s
    limit = after_push - STABLE_BEFORE_END_S
    relations = []
    for entry in (
        e for e in entries if e.experiment == experiment and e.choice.ref.has_composition
    ):
        label = entry.choice.label

        def stable(entry: RunEntry = entry, label: str = label) -> tuple[bool, str]:
            settling = metric(entry, "settling_time_s", label)
            if entry.result.termination is Termination.SAFETY_STOP:
                return False, f"safety stop: {entry.result.ending.detail}"
            return settling < limit, f"settles in {settling:.2f} s"

        relations.append(
            check(
                experiment,
                f"{label}: the closed loop is stable after the push",
                "stable (the paper's design; sampled-loop analysis)",
                stable,
                f"holds with no safety stop and the motion settled {STABLE_BEFORE_END_S:g} s "
                "before the run ends",
            )
        )
    return relations


def point_relations(
    rows: Sequence[dict[str, Any]],
    experiments: Sequence[str],
    parameter_names: Sequence[str],
    duration_s: float | None = None,
) -> list[PointRelation]:
    """Every relation at every point of these rows."""
    by_point: dict[str, list[dict[str, Any]]] = {}
    for row in rows:
        by_point.setdefault(str(row["point_id"]), []).append(row)
    found = []
    for point_id, point_rows in by_point.items():
        values = {name: point_rows[0].get(name) for name in parameter_names}
        entries = [entry_of(row) for row in point_rows]
        for name in experiments:
            relations = EXPERIMENTS[name].relations(entries)
            relations += stability_relations(name, entries, duration_s)
            found += [PointRelation(point_id, values, relation) for relation in relations]
    return found


def fractions(found: Sequence[PointRelation]) -> list[RelationFraction]:
    """Per relation: at how many points it holds, does not, could not be checked."""
    counts: dict[tuple[str, str], list[int]] = {}
    for item in found:
        tally = counts.setdefault(item.key, [0, 0, 0])
        holds = item.relation.holds
        tally[0 if holds else 1 if holds is False else 2] += 1
    return [
        RelationFraction(experiment, claim, *tally) for (experiment, claim), tally in counts.items()
    ]
