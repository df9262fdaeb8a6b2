"""A plug-in controller tried once on a copy, before anything opens: what can be judged then is
refused with exit 2 (the file and what is wrong) instead of being found with torque on.

The copy is built for the run's robot and started at the experiment's start posture, at rest
(motor and link angles at the start reference, no velocity, no current), and stepped
PREFLIGHT_STEPS times: it must return one finite goal per joint each time, log the terms it
declares, and step in less than the loop's period (else it would overrun every tick on the
hardware's wall clock). What only the run can show (a goal that diverges later, an exception
on some tick) the supervisor handles during the run: torque off, the traceback in events.jsonl.
"""

from __future__ import annotations

import time
import traceback
from typing import TYPE_CHECKING

import numpy as np

from hil.controllers.contract import ControlInput, Controller
from hil.controllers.registry import build
from hil.controllers.robot_model import robot_model
from hil.controllers.setup import controller_setup

if TYPE_CHECKING:
    from hil.config import Config
    from hil.experiments import Experiment
    from hil.vocabulary import ControllerChoice

PREFLIGHT_STEPS = 5


def preflight(config: Config, experiment: Experiment, choice: ControllerChoice) -> str | None:
    """What is wrong with the chosen controller on this run (None: nothing found)."""
    n, period = len(config.joints), config.loop.period_s
    robot = robot_model(config)
    support = experiment.support(0.0)
    robot.set_support(support)
    start = np.array(np.broadcast_to(experiment.reference(0.0), (n,)), dtype=float)
    setup = controller_setup(config, period, robot, start, robot.lqr_contacts([support])[0])
    try:
        controller = build(choice, setup, config.controller.params)
    except Exception as exc:  # noqa: BLE001 - any error of the user's code, said
        return f"building it raised {_said(exc)}"
    durations = []
    for tick in range(PREFLIGHT_STEPS):
        state = _at_rest(start, tick, period, support, experiment)
        try:
            if tick == 0:
                controller.start(state)
            began = time.perf_counter()
            goal = controller.step(state)
            durations.append(time.perf_counter() - began)
        except Exception as exc:  # noqa: BLE001
            return f"{'start/' if tick == 0 else ''}step raised {_said(exc)}"
        problem = goal_problem(goal, n) or terms_problem(controller, n)
        if problem is not None:
            return f"at the start posture, at rest: {problem}"
        controller.applied(np.asarray(goal, dtype=float))
    slowest = float(np.median(durations))
    if slowest > period:
        return (
            f"a step takes {slowest * 1e3:.1f} ms, longer than the loop's period "
            f"{period * 1e3:g} ms: it would overrun every tick"
        )
    return None


def goal_problem(goal: object, n_joints: int) -> str | None:
    """Why `goal` is not a goal for n joints (None: it is)."""
    try:
        array = np.asarray(goal, dtype=float)
    except (TypeError, ValueError):
        return f"step() returned {type(goal).__name__}, not an array of {n_joints} goals"
    if array.shape != (n_joints,):
        return f"step() returned shape {array.shape}, not ({n_joints},)"
    if np.count_nonzero(np.isfinite(array)) != n_joints:
        return f"step() returned a goal that is not finite: {array.tolist()}"
    return None


def terms_problem(controller: Controller, n_joints: int) -> str | None:
    """Why the controller's terms() does not match its term_names (None: it does)."""
    names = controller.term_names
    try:
        terms = controller.terms()
    except Exception as exc:  # noqa: BLE001
        return f"terms() raised {_said(exc)}"
    if set(terms) != set(names):
        return f"terms() gave {sorted(terms)}, its term_names are {list(names)}"
    for name in names:
        if np.shape(terms[name]) != (n_joints,):
            return f"terms()[{name!r}] has shape {np.shape(terms[name])}, not ({n_joints},)"
    return None


def _at_rest(
    start: np.ndarray, tick: int, period: float, support: object, experiment: Experiment
) -> ControlInput:
    zeros = np.zeros_like(start)
    return ControlInput(
        tick=tick,
        time_s=tick * period,
        motor_angle_rad=start.copy(),
        link_angle_rad=start.copy(),
        motor_velocity_rad_s=zeros.copy(),
        motor_current_a=zeros.copy(),
        reference_rad=start.copy(),
        goal_in_force_rad=start.copy(),
        ticks_since_step=0 if tick == 0 else 1,
        support=support,
        planned_motion=experiment.planned_motion(tick * period),
    )


def _said(exc: BaseException) -> str:
    """An exception with the last line of the user's code it came from."""
    frames = traceback.extract_tb(exc.__traceback__)
    where = f" at {frames[-1].filename}:{frames[-1].lineno}" if frames else ""
    return f"{type(exc).__name__}: {exc}{where}"
