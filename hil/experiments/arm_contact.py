"""Contact of a fixed-base robot's tool with a block (the testbed's object contact, Kim et al.,
ICRA 2018, Sec. IV-B, Fig. 5, on an arm): a joint-space reference drives the tool into a block
fixed in the world (`World.block`) that stands on a force sensor (`[force_sensor]`: the log's
`contact_force_n`, the block's normal force), and ends past it, so that the joints' position
servos press on it.

Metrics: the testbed contact's (hil/experiments/contact.py `contact_metrics`: contact time,
peak and mean force, overload trip and its time after contact, force drift), from the log.

What the paper's relations predict for it (`relations`, said as predictions: the paper has no
arm): `pid`, stiff at every joint, presses until a protection acts (the actuator's overload
protection, or the current guard's safety stop before it); the DOB, which takes the contact
for a disturbance, stays compliant (no trip, no stop) and presses on the block less than pid.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hil.experiments.arm import JointPoseExperiment
from hil.experiments.contact import (
    CONTACT_COLUMNS,
    contact_metrics,
    contact_time_s,
    no_contact_reason,
    plot_contact_comparison,
    presses_less_than_pid,
)
from hil.output.plots import ComparisonRun, WorldMarks
from hil.output.records import RunEntry
from hil.output.report import Column, Missing, Relation, check, find, metric
from hil.output.rundir import RunData
from hil.vocabulary import ControllerKind, Termination


@dataclass(frozen=True)
class ArmContactExperiment(JointPoseExperiment):
    """Drive the tool into `world.block` along `moves` (module docstring). `pressing_joint`:
    the index of the joint whose move presses on the block (the figure's angle)."""

    pressing_joint: int = 0

    def metrics(self, run: RunData) -> dict[str, Any]:
        return contact_metrics(run, lambda: self._no_contact(run))

    def _no_contact(self, run: RunData) -> str:
        end_s = float(run.time_s[-1]) - run.experiment_start_s if run.time_s.size else 0.0
        ramp_end = max((m.start_s + m.duration_s for m in self.moves), default=0.0)
        return no_contact_reason(end_s, ramp_end, "the reference's move ends")

    def marks(self, run: RunData) -> WorldMarks:
        marks = super().marks(run)
        return WorldMarks(marks.pushes, None, contact_time_s(run), marks.title, self.name)

    @property
    def report_columns(self) -> tuple[Column, ...]:
        return CONTACT_COLUMNS

    def comparison_figure(
        self, runs: Sequence[ComparisonRun], path: Path, setup: str
    ) -> Path | None:
        if not runs:
            return None
        return plot_contact_comparison(runs, self, path, setup, joint=self.pressing_joint)

    def relations(self, entries: Sequence[RunEntry]) -> list[Relation]:
        return arm_contact_relations(self.name, entries)


def _stopped_by(entry: RunEntry) -> str | None:
    """What protection acted on a run: the overload trip, or a safety stop (its reason)."""
    result = entry.result
    if result.metrics.get("overload_tripped"):
        after = result.metrics.get("trip_time_after_contact_s")
        when = f" {after:.2f} s after contact" if after is not None else ""
        return f"overload trip{when}"
    if result.termination is Termination.SAFETY_STOP:
        first = result.safety_events[0] if result.safety_events else None
        at = f" at {first.time_s:.2f} s" if first is not None else ""
        return f"safety stop ({result.ending}){at}"
    return None


def arm_contact_relations(exp: str, entries: Sequence[RunEntry]) -> list[Relation]:
    """The testbed's contact claims (Sec. IV-B) as predictions for a fixed-base robot."""
    pid = find(entries, exp, ControllerKind.PID)
    relations = []

    def pid_protected() -> tuple[bool, str]:
        peak = metric(pid, "peak_contact_force_n", "pid")
        assert pid is not None  # metric() raised Missing otherwise
        stopped = _stopped_by(pid)
        return stopped is not None, f"peak {peak:.1f} N, " + (stopped or "nothing acted")

    relations.append(
        check(
            exp,
            "pid presses on the block until a protection acts (overload trip or current guard)",
            "testbed: off ~1.5 s after contact, >= 70 N",
            pid_protected,
            "a prediction for this robot: the testbed's claim, not a figure for it",
        )
    )
    for entry in (e for e in entries if e.experiment == exp and e.choice.uses_kdist):
        label = entry.choice.label

        def compliant(entry: RunEntry = entry, label: str = label) -> tuple[bool, str]:
            if metric(entry, "contact_time_s", label) is None:
                raise Missing(f"the {label} run never touched the block")
            mean = metric(entry, "mean_contact_force_n", label)
            stopped = _stopped_by(entry)
            return stopped is None, f"mean {mean:.1f} N, " + (stopped or "no trip, no stop")

        relations.append(
            check(
                exp,
                f"{label} stays compliant on contact (no trip, no stop)",
                "testbed: 20-40 N, no trip",
                compliant,
                "a prediction for this robot",
            )
        )
        relations.append(
            presses_less_than_pid(
                exp, entry, pid, label, "testbed: 20-40 N vs >= 70 N", "a prediction for this robot"
            )
        )
    return relations
