"""The paper's claims about walking (Kim et al., ICRA 2018, Sec. IV-C, V), checked against the
walking runs' metrics (hil/experiments/walking.py). A walk that fell, stopped or took fewer steps
than planned does not count as walking.
"""

from __future__ import annotations

import contextlib
import functools
import math
from collections.abc import Sequence

from hil.experiments.walking_kinematics import PlannedWalk
from hil.output.records import RunEntry
from hil.output.report import Missing, Relation, check, find, metric
from hil.vocabulary import ControllerKind

ZMP_CLAIM_M = 0.02  # "The ZMP tracking error was within 2cm" (Sec. V)


def _walked(experiment: PlannedWalk, entry: RunEntry | None, what: str) -> tuple[bool, str]:
    """Did the run walk its whole plan (no fall, no safety stop), and a summary of it."""
    steps = metric(entry, "steps_completed", what)
    fell = metric(entry, "fell", what)
    stopped = metric(entry, "stopped_at_s", what)
    ok = not fell and stopped is None and steps == experiment.n_steps
    text = f"{steps}/{experiment.n_steps} steps"
    if stopped is not None:
        text += f", safety stop at {stopped:.2f} s"
    if fell:
        text += f", fell at {metric(entry, 'fell_at_s', what):.2f} s"
    return ok, text


def _millimetres(value: float | None) -> str:
    return "-" if value is None else f"{value * 1e3:.1f} mm"


def _rms_of(entry: RunEntry | None, what: str) -> float:
    value = metric(entry, "zmp_rms_error_m", what)
    return math.inf if value is None else float(value)


def _within_2cm(experiment: PlannedWalk, dob: RunEntry | None) -> tuple[bool, str]:
    lateral = metric(dob, "zmp_max_error_lateral_m", "gc+lqr+dob")
    sagittal = metric(dob, "zmp_max_error_sagittal_m", "gc+lqr+dob")
    ok, steps = _walked(experiment, dob, "gc+lqr+dob")
    holds = ok and lateral <= ZMP_CLAIM_M and sagittal <= ZMP_CLAIM_M
    return holds, (
        f"gc+lqr+dob: max |error| y {_millimetres(lateral)}, x {_millimetres(sagittal)} ({steps})"
    )


def _beats(
    experiment: PlannedWalk,
    winners: Sequence[tuple[RunEntry | None, str]],
    losers: Sequence[tuple[RunEntry | None, str]],
) -> tuple[bool, str]:
    """Each winner walked, and each loser either did not or had a larger ZMP rms."""
    holds = True
    parts = []
    for entry, what in (*winners, *losers):
        _, steps = _walked(experiment, entry, what)
        parts.append(f"{what} {_millimetres(metric(entry, 'zmp_rms_error_m', what))} ({steps})")
    for winner, win_name in winners:
        win_ok, _ = _walked(experiment, winner, win_name)
        for loser, lose_name in losers:
            lose_ok, _ = _walked(experiment, loser, lose_name)
            better = _rms_of(winner, win_name) < _rms_of(loser, lose_name)
            holds = holds and win_ok and (not lose_ok or better)
    return holds, "ZMP rms while walking: " + ", ".join(parts)


def _none_walked(experiment: PlannedWalk, entries: Sequence[RunEntry | None]) -> bool:
    with contextlib.suppress(Missing):
        return not any(_walked(experiment, e, e.choice.label)[0] for e in entries if e)
    return False


def walking_relations(experiment: PlannedWalk, entries: Sequence[RunEntry]) -> list[Relation]:
    """The paper's claims that concern this experiment (a walk that fell, stopped or took fewer
    steps than planned does not count as walking)."""
    exp = experiment.name
    dob = find(entries, exp, ControllerKind.GC_LQR_DOB)
    gc = find(entries, exp, ControllerKind.GC)
    lqr = find(entries, exp, ControllerKind.GC_LQR)
    pid = find(entries, exp, ControllerKind.PID)
    relations: list[Relation] = []
    if experiment.object_footstep is None:
        relations.append(
            check(
                exp,
                "GC+LQR+DOB tracks the ZMP reference within 2 cm (lateral and sagittal)",
                "Sec. V: 'The ZMP tracking error was within 2cm from the reference ZMP "
                "trajectory' (Fig. 7)",
                lambda: _within_2cm(experiment, dob),
            )
        )
    if exp == "walk-slow":
        for entry, name in ((pid, "pid"), (gc, "gc"), (lqr, "gc+lqr"), (dob, "gc+lqr+dob")):
            relations.append(
                check(
                    exp,
                    f"{_named(name)} completes the slow walk (every step, no fall, no safety stop)",
                    "Sec. IV-C, Fig. 7(a): all four controllers walk slowly",
                    functools.partial(_walked, experiment, entry, name),
                )
            )
        relations.append(
            check(
                exp,
                "GC+LQR and GC+LQR+DOB track the ZMP better than GC in slow walking",
                "Sec. IV-C, Fig. 7(a): 'obviously better than those of the other controllers'",
                lambda: _beats(experiment, [(lqr, "gc+lqr"), (dob, "gc+lqr+dob")], [(gc, "gc")]),
            )
        )
    if exp == "walk-dynamic":
        pid_walked = functools.partial(_walked, experiment, pid, "pid")
        relations.append(
            check(
                exp,
                "the default walking controller cannot walk dynamically",
                "Sec. IV-C: 'the robot with the default algorithm could not walk'",
                lambda: (not pid_walked()[0], "pid: " + pid_walked()[1]),
                note="no controller walked here: this does not tell pid apart"
                if _none_walked(experiment, (dob, gc, lqr))
                else "",
            )
        )
        relations.append(
            check(
                exp,
                "GC+LQR+DOB tracks the ZMP better than GC and GC+LQR in dynamic walking",
                "Sec. IV-C, Fig. 7(b): the DOB absorbs the landing impact",
                lambda: _beats(experiment, [(dob, "gc+lqr+dob")], [(gc, "gc"), (lqr, "gc+lqr")]),
            )
        )
    if experiment.object_footstep is not None:

        def keeps_walking() -> tuple[bool, str]:
            ok, steps = _walked(experiment, dob, "gc+lqr+dob")
            height = metric(dob, "object_foot_height_m", "gc+lqr+dob")
            return ok, f"gc+lqr+dob: {steps}; the foot on the object {_millimetres(height)} up"

        relations.append(
            check(
                exp,
                "GC+LQR+DOB keeps walking after stepping on an unknown object",
                "Sec. IV-C, Fig. 8: 'walking stability was preserved'",
                keeps_walking,
                note=_object_note(experiment),
            )
        )
    return relations


def _named(controller: str) -> str:
    """The paper's names: `pid` on a walk is its default controller (the actuator's own
    position control with the lab's walking scheme)."""
    return "the default controller (pid)" if controller == "pid" else controller.upper()


def _object_note(experiment: PlannedWalk) -> str:
    boxes = experiment.world.floor_objects
    height = f"a box {boxes[0].height_m * 1e3:.0f} mm high" if boxes else "no box"
    return f"{height} under footstep {(experiment.object_footstep or 0) + 1}"
