"""`hil bench loop`'s first part: each controller's compute per tick (`step` +
`notify_applied`) for 1 and 12 joints (on a robot whose model depends on its posture, the
humanoid: its own joints with its gravity compensator about its bench experiment's first
posture, its standing one), all cases interleaved tick by tick so that a burst of machine load
falls on all of them alike."""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from controller import CONTROLLER_NAMES, JointController
from drivers.timing import DurationStats as Distribution
from hil.bench.bus import JOINT_COUNTS
from hil.bench.common import config_with_joints
from hil.config import Config
from hil.loop import build_controller, robot_model
from hil.robots import profile_of
from hil.vocabulary import ControllerChoice

CONTROLLER_WARMUP_TICKS = 20


def _controller_inputs(
    n_joints: int, ticks: int, period_s: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Plausible motor / link / reference angles [rad] (ticks x n): a slow swing, a small
    deflection. The controllers' cost does not depend on the values; they just stay finite."""
    time_s = np.arange(ticks)[:, None] * period_s
    phase = np.arange(n_joints)[None, :] * 0.3
    reference = 0.2 * np.sin(2 * np.pi * 0.5 * time_s + phase)
    link = reference + 0.01 * np.sin(2 * np.pi * 3.0 * time_s + phase)
    motor = link + 0.005 * np.cos(2 * np.pi * 3.0 * time_s + phase)
    return motor, link, reference


def bench_controllers(
    base: Config,
    ticks: int,
    *,
    joint_counts: Sequence[int] = JOINT_COUNTS,
    names: Sequence[str] = CONTROLLER_NAMES,
    warmup: int = CONTROLLER_WARMUP_TICKS,
) -> list[dict[str, Any]]:
    """Time step + notify_applied of every (n joints, controller), interleaved tick by tick.

    Each tick runs every case once, the order rotated by one each tick, so a burst of machine
    load falls on all of them alike. build_s is make_controller's time (LQR design included).
    """
    period_s = base.loop.period_s
    kdist = base.controller.kdist
    bench = profile_of(base).bench_experiment
    robot = robot_model(base)
    own_joints = robot.rescheduled
    if own_joints:  # the robot's own joints, about its bench experiment's first posture
        joint_counts = (len(base.joints),)
        posture = np.broadcast_to(bench.reference(0.0), (len(base.joints),))
    cases: list[tuple[int, str]] = [(n, name) for n in joint_counts for name in names]
    controllers: list[JointController] = []
    build_s: list[float] = []
    inputs: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
    total = warmup + ticks
    for n_joints, name in cases:
        started = time.perf_counter()
        choice = ControllerChoice(name, kdist)
        if own_joints:
            contact = robot.lqr_contacts([bench.support(0.0)])[0]
            controller = build_controller(base, choice, period_s, robot, posture, contact)
        else:
            controller = build_controller(config_with_joints(base, n_joints), choice, period_s)
        build_s.append(time.perf_counter() - started)
        if n_joints not in inputs:
            inputs[n_joints] = _controller_inputs(n_joints, total, period_s)
            if own_joints:
                inputs[n_joints] = tuple(a + posture for a in inputs[n_joints])  # type: ignore[assignment]
        motor, link, reference = inputs[n_joints]
        controller.reset(motor[0], link[0], reference[0])
        controllers.append(controller)
    durations_s = np.empty((len(cases), total))
    order = list(range(len(cases)))
    clock = time.perf_counter
    for k in range(total):
        shift = k % len(order)
        for index in order[shift:] + order[:shift]:
            controller = controllers[index]
            motor, link, reference = inputs[cases[index][0]]
            started = clock()
            goal = controller.step(motor[k], link[k], reference[k])
            controller.notify_applied(goal)
            durations_s[index, k] = clock() - started
    results = []
    for index, (n_joints, name) in enumerate(cases):
        stats = Distribution.of(durations_s[index, warmup:])
        results.append(
            {
                "n_joints": n_joints,
                "controller": name,
                "ticks": stats.count,
                "median_s": stats.median_s,
                "p99_s": stats.p99_s,
                "max_s": stats.max_s,
                "build_s": build_s[index],
            }
        )
    return results
