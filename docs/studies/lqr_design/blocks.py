"""Which feedback the soles' modes turn against: the closed chain on the servo cascade with the
paper's cost (22) integrated over the tick ("continuous-cost", R = 1), each increment's gain
zeroed in turn, on the linearised emulated robot standing on both feet.

Run from this folder: PYTHONPATH=../../.. python blocks.py
"""

import dataclasses

import numpy as np

from controller.humanoid import SupportState
from hil.config import load_config
from hil.loop import build_controller, robot_model
from hil.vocabulary import ControllerChoice
from sim_backend.humanoid.linear import Friction, linearise
from tests.support.humanoid_loop import closed_loop, loop_modes, settled_robot
from designs import DT, READY, configured


def main() -> None:
    config = configured(
        load_config(robot="dyros-jet"),
        {"controller": {"discretization": "continuous-cost", "r_input": 1.0}},
    )
    robot = settled_robot(READY, SupportState.DOUBLE)
    model = robot_model(config)
    contact = model.lqr_contacts([SupportState.DOUBLE])[0]
    choice = ControllerChoice("gc+lqr", 0.2)
    gain = build_controller(config, choice, DT, model, robot.plant.link_angle_rad, contact).lqr_gain
    ticks = {f: linearise(robot, DT, f) for f in Friction}
    n = 12
    state = gain.state_increment_gain

    def without(block: str):
        if block == "motor velocity":
            return dataclasses.replace(gain, motor_velocity_increment_gain=np.zeros((n, n)))
        columns = {"motor angle": 0, "link angle": 1, "link velocity": 2}
        if block not in columns:
            return gain
        zeroed = state.copy()
        zeroed[:, columns[block] * n : (columns[block] + 1) * n] = 0.0
        return dataclasses.replace(gain, state_increment_gain=zeroed)

    for block in ("nothing", "motor angle", "motor velocity", "link angle", "link velocity"):
        cells = [
            f"{f.value}: {loop_modes(t, closed_loop(t, without(block))).text()}"
            for f, t in ticks.items()
        ]
        print(f"without the {block:14s} increment: " + "; ".join(cells))


if __name__ == "__main__":
    main()
