"""A rescheduled robot's LQR rescheduling cost (off the 200 Hz path), before and after.

What one reschedule costs: Sm of (19) at a posture (pinocchio), then the gain on it. The gain
is timed in two ways, taken in turn on every posture (A B A B ..., so a burst of machine load
falls on both alike):

    diagonal Sm (the lab's design)  "per-joint scipy": n one-joint problems, one
                                    scipy.linalg.solve_discrete_are each (the product before);
                                    "batched": the n problems as one batch
                                    (controller.riccati.discrete_lqr_batch)
    coupled (full, closed-chain)    "scipy QZ": scipy.linalg.solve_discrete_are on the one
                                    problem (the product before); "doubling": the same problem
                                    by the doubling algorithm (controller.riccati)

The postures walk a little (1 mrad per design on every joint), as a walking robot's do between
two reschedules. Designs run with one BLAS thread, as the scheduler runs them; the "paper-yield"
DOB scale (a diagonal design on the same Sm) is part of "after" when configured.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from controller import ControllerKind, Coupling, TrackingGain, design_discrete_tracking_lqr
from controller.model import validate_sm
from drivers.timing import DurationStats as Distribution
from hil.config import Config
from hil.loop import build_controller, robot_model
from hil.robots import profile_of
from hil.vocabulary import ControllerChoice

POSTURE_STEP_RAD = 0.001


def bench_gain_schedule(base: Config, designs: int = 20) -> dict[str, Any] | None:
    """The humanoid's rescheduling cost (module docstring); None for a robot whose Sm is
    constant."""
    robot = robot_model(base)
    if not robot.rescheduled:
        return None
    bench = profile_of(base).bench_experiment
    period_s = base.loop.period_s
    posture = np.broadcast_to(bench.reference(0.0), (len(base.joints),))
    contact = robot.lqr_contacts([bench.support(0.0)])[0]
    choice = ControllerChoice(ControllerKind.GC_LQR, base.controller.kdist)
    params = build_controller(base, choice, period_s, robot, posture, contact).params  # type: ignore[attr-defined]
    designer = params.gain_designer(period_s)
    scipy_designer = dataclasses.replace(params).gain_designer(period_s)
    scipy_designer.reference_solver = True
    diagonal = params.lqr_coupling == Coupling.DIAGONAL

    def before(sm: np.ndarray) -> object:
        if not diagonal:
            return scipy_designer.design(sm)
        return [  # one scipy DARE per joint, as the product did before
            design_discrete_tracking_lqr(
                params.joints.joint(joint),
                sm[joint : joint + 1, joint : joint + 1],
                period_s,
                params.lqr_weights,
                params.discretisation,
                "full",
                None if params.servo_cascade is None else params.servo_cascade.joint(joint),
            )
            for joint in range(params.n_joints)
        ]

    def after(sm: np.ndarray) -> TrackingGain:
        return designer.design(sm)

    sm_s = np.empty(designs)
    before_s, after_s = np.empty(designs), np.empty(designs)
    with threadpool_limits(limits=1, user_api="blas"):
        for k in range(designs):
            started = time.perf_counter()
            sm = validate_sm(robot.sm(posture + POSTURE_STEP_RAD * k, contact), params.n_joints)
            sm_s[k] = time.perf_counter() - started
            timed: list[tuple[Callable[[np.ndarray], object], np.ndarray]] = [
                (before, before_s),
                (after, after_s),
            ]
            for design, durations in timed if k % 2 == 0 else timed[::-1]:
                started = time.perf_counter()
                design(sm)
                durations[k] = time.perf_counter() - started
    labels = ("per-joint scipy", "batched") if diagonal else ("scipy QZ", "doubling")
    return {
        "sm": dataclasses.asdict(Distribution.of(sm_s)),
        "before": {"label": labels[0], **dataclasses.asdict(Distribution.of(before_s))},
        "after": {"label": labels[1], **dataclasses.asdict(Distribution.of(after_s))},
        "reschedule_period_s": base.model.gain_reschedule_period_s,
        "sm_coupling": base.model.sm_coupling,
        "sm_contact": base.model.sm_contact,
        "servo_model": base.model.servo_model,
    }


def gain_schedule_lines(schedule: dict[str, Any]) -> list[str]:
    """The report's lines for `bench_gain_schedule`'s result."""

    def text(entry: dict[str, Any]) -> str:
        return Distribution(**{k: v for k, v in entry.items() if k != "label"}).text()

    return [
        f"  LQR rescheduling, every {schedule['reschedule_period_s'] * 1e3:g} ms off the 200 Hz "
        f"path (Sm {schedule['sm_coupling']}, {schedule['sm_contact']}; servo model "
        f"{schedule['servo_model']}), median / p99 / max [ms]:",
        "    Sm of (19) " + Distribution(**schedule["sm"]).text(),
        f"    gain, {schedule['before']['label']} (before) " + text(schedule["before"]),
        f"    gain, {schedule['after']['label']} (after)  " + text(schedule["after"]),
    ]
