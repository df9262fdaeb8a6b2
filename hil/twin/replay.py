"""A recorded run replayed on an emulated robot, in this process (hil.wiring.in_process).

Open loop (`replay_goals`): the run's goals and torque states sent again, tick by tick, in the
lock-step order of the loop (read, torque on or off as the record says it was over the tick,
the goal written): what the emulator does with the very commands the robot got. Two readings:
`Reading.DRIVERS`, what the drivers would read (quantised, with the sensors' noise: the
in-process bus), and `Reading.PLANT`, the emulated plant's own state in the host's frame (the
configuration's zero errors added; the current the motor's torque over the torque constant; no
quantisation, no noise), smooth in the emulator's figures: what the fit differentiates.

Closed loop (`replay_closed_loop`): the recorded experiment run again with the recorded
controller (rebuilt through the registry from meta.json: its spec, Kdist, reading of (25) and
GC compliance) on the emulator of `config`, through `hil run`'s own session (in process).
"""

from __future__ import annotations

import enum
import tempfile
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from hil.config import Config
from hil.controllers.registry import resolve
from hil.output.rundir import load_run
from hil.session.session import Session, Setup
from hil.twin.runs import FORCE_SIGNAL, RecordedRun
from hil.vocabulary import ControllerChoice
from hil.wiring.emulation import emulator_spec
from hil.wiring.in_process import InProcessJointBus
from sim_backend.flexible_robot import FlexibleJointRobot

if TYPE_CHECKING:
    from sim_backend.hardware import EmulatedHardware


class Reading(enum.Enum):
    DRIVERS = "drivers"  # what the drivers read (the in-process bus)
    PLANT = "plant"  # the plant's state in the host's frame (smooth in the figures)


@dataclass(frozen=True)
class Replayed:
    """The replayed signals at the recorded ticks: (ticks, joints) each; force (ticks,) or None."""

    motor_angle_rad: np.ndarray
    link_angle_rad: np.ndarray
    motor_current_a: np.ndarray
    force_n: np.ndarray | None
    # MuJoCo found the integration unstable (and reset its state): figures no robot has
    unstable: bool = False

    def signal(self, name: str) -> np.ndarray:
        if name == "deflection_rad":
            return self.link_angle_rad - self.motor_angle_rad
        return np.asarray(getattr(self, name))


def replay_goals(
    config: Config, run: RecordedRun, reading: Reading = Reading.DRIVERS, ticks: int | None = None
) -> Replayed:
    """The run's goals and torque states on the emulator of `config` (module docstring); the
    first `ticks` rows only if given."""
    n_ticks = run.ticks if ticks is None else min(ticks, run.ticks)
    spec = emulator_spec(config, experiment=run.experiment, seed=run.seed)
    bus = InProcessJointBus(config, spec)
    bus.open()
    try:
        return _play(bus, run, reading, n_ticks)
    finally:
        bus.close()


def _play(bus: InProcessJointBus, run: RecordedRun, reading: Reading, ticks: int) -> Replayed:
    goals = run.goals()
    torque = run.torque_on_over_tick()
    n = goals.shape[1]
    out = np.full((3, ticks, n), np.nan)
    force = np.full(ticks, np.nan) if run.force() is not None else None
    motor_error = link_error = np.zeros(n)
    if reading is Reading.PLANT:  # the host reads the physical angle plus the zero error
        motor_error, link_error = (np.array(e) for e in bus.config.emulator.zero_errors(n))
    on = False
    for k in range(ticks):
        if reading is Reading.DRIVERS:
            sample = bus.read()
            out[0, k] = sample.motor_angle_rad
            out[1, k] = sample.link_angle_rad
            out[2, k] = sample.motor_current_a
            if force is not None:
                force[k] = sample.extra.get(FORCE_SIGNAL, np.nan)
        else:  # the plant's state: the tick's SYNC without the sensors' readings
            testbed = bus.testbed
            assert testbed is not None
            testbed.sync()
            out[:, k] = _plant_state(testbed.robot)
            out[0, k] += motor_error
            out[1, k] += link_error
            if force is not None:
                force[k] = sum(j.plant.contact_force_n() for j in testbed.robot.joints)
        if torque[k] and not on:
            bus.enable()
            on = True
        elif on and not torque[k]:
            bus.disable()
            on = False
        if on and np.isfinite(goals[k]).all():
            bus.write(goals[k])
    return Replayed(out[0], out[1], out[2], force, _unstable(bus))


def _unstable(bus: InProcessJointBus) -> bool:
    """Whether MuJoCo warned of an unstable integration (a bad acceleration) in the replay."""
    hardware = bus.testbed.robot if bus.testbed is not None else None
    robot = getattr(hardware, "robot", None)
    plants = [robot.plant] if isinstance(robot, FlexibleJointRobot) else [
        j.plant for j in getattr(hardware, "joints", ())
    ]  # fmt: skip
    bad = mujoco.mjtWarning.mjWARN_BADQACC
    return any(int(p.data.warning[bad].number) > 0 for p in plants)


def _plant_state(hardware: EmulatedHardware) -> np.ndarray:
    """(3, joints): the plant's motor angles, link angles and the motor's torque over the
    torque constant (the current without its noise), physical frame."""
    robot = getattr(hardware, "robot", None)
    if isinstance(robot, FlexibleJointRobot):  # the humanoid, a fixed-base robot: one plant
        plant = robot.plant
        current = plant.motor_torque_nm / np.asarray(robot.bank.torque_constant)
        return np.stack([plant.motor_angle_rad, plant.link_angle_rad, current])
    joints = hardware.joints  # the testbed's EmulatedJoint per joint
    return np.array(
        [
            [j.plant.motor_angle_rad for j in joints],
            [j.plant.link_angle_rad for j in joints],
            [j.plant.motor_torque_nm / j.bank.torque_constant[0] for j in joints],
        ]
    )


def replay_closed_loop(config: Config, run: RecordedRun, out_root: Path | None = None) -> Replayed:
    """The run's experiment with its controller on the emulator of `config` (in process); the
    replayed run's directory is made under `out_root` (a temporary one if None) and read back.
    Rows past the replay's end are NaN (a replay that stopped earlier than the record)."""
    meta = run.controller
    choice = ControllerChoice(
        resolve(str(meta["controller_spec"] or meta["controller"])),
        float(meta["kdist"] or 0.0),
        meta["reading"],
    )
    if choice.ref.has_gravity_compensator and meta["gc_compliance"]:
        choice = replace(choice, gc_compliance=meta["gc_compliance"])
    duration = run.experiment_duration_s
    with tempfile.TemporaryDirectory(prefix="hil-twin-") as scratch:
        session = Session(
            config,
            Setup.IN_PROCESS,
            seed=run.seed,
            out_root=Path(out_root) if out_root is not None else Path(scratch),
            plots=False,
            quiet=True,
            mcap=False,
        )
        result = session.run_one(run.experiment, choice, duration_s=duration, print_result=False)
        replayed = load_run(result.out_dir)
    n = len(run.joint_names)
    rows = min(len(replayed.time_s), run.ticks)
    out = np.full((3, run.ticks, n), np.nan)
    for index, name in enumerate(("motor_angle_rad", "link_angle_rad", "motor_current_a")):
        out[index, :rows] = np.column_stack(replayed.per_joint(name))[:rows]
    force = None
    if run.force() is not None:
        force = np.full(run.ticks, np.nan)
        force[:rows] = np.asarray(replayed.columns[FORCE_SIGNAL], dtype=float)[:rows]
    return Replayed(out[0], out[1], out[2], force)
