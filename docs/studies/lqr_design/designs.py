"""Every design's loop on the linearised emulated robot, per support state and friction side.

Run from this folder: PYTHONPATH=../../.. python designs.py [R_INPUT ...]
(the extra arguments: the input weights R to try for "ours"; default the configuration's).
"""

import sys

import numpy as np

from controller.humanoid import (
    LegModel,
    PostureTarget,
    SupportState,
    WALKING_READY_LEG_ANGLES_RAD,
    solve_posture,
)
from hil.config import load_config
from hil.loop import build_controller, robot_model
from hil.vocabulary import ControllerChoice
from sim_backend.humanoid.linear import Friction, linearise
from tests.support.humanoid_loop import URDF_PATH, Dob, closed_loop, loop_modes, settled_robot

DT = 0.005
READY = np.array(WALKING_READY_LEG_ANGLES_RAD)
PAPERS_CONTROLLER = {
    "discretization": "euler",
    "r_input": 1.0,
    "kdist_reference": "per-tick",
    "reference_feedforward": False,
}
FIRST_ORDER = {"servo_model": "first-order"}
CONFIGS = {
    "paper (support foot, diagonal, Euler)": {
        "model": {**FIRST_ORDER, "sm_contact": "support-foot", "sm_coupling": "diagonal"},
        "controller": PAPERS_CONTROLLER,
    },
    "lab (both feet, diagonal, Euler)": {
        "model": {**FIRST_ORDER, "sm_coupling": "diagonal"},
        "controller": PAPERS_CONTROLLER,
    },
    "closed-chain (first-order servo, Euler)": {
        "model": FIRST_ORDER,
        "controller": PAPERS_CONTROLLER,
    },
}
OURS = {"model": {}, "controller": {}}  # the configuration's default


def postures() -> dict[str, tuple[np.ndarray, SupportState]]:
    legs = LegModel(URDF_PATH.read_text())
    lift = 0.05
    left = PostureTarget((0, 0.1278, 0), (0, -0.1278, lift), (0, 0.1278), 0.87)
    right = PostureTarget((0, 0.1278, lift), (0, -0.1278, 0), (0, -0.1278), 0.87)
    return {
        "double": (READY, SupportState.DOUBLE),
        "left": (solve_posture(legs, left, READY).leg_angles_rad, SupportState.LEFT),
        "right": (solve_posture(legs, right, READY).leg_angles_rad, SupportState.RIGHT),
    }


def configured(base, changes):
    """The configuration with these keys changed (all sections at once, then validated)."""
    return base.replaced(
        **{section: getattr(base, section).model_copy(update=v) for section, v in changes.items()}
    )


def gains(config, robot, support, angles, kdist):
    """The gain the product designs there for gc+lqr, and the DOB as gc+lqr+dob runs it."""
    model = robot_model(config)
    contacts = model.lqr_contacts([support] * 3)
    contact = contacts[1]
    choice = ControllerChoice("gc+lqr+dob", kdist)
    controller = build_controller(config, choice, DT, model, angles, contact)
    return controller.lqr_gain, Dob(kdist, controller.params), contact


def main() -> None:
    base = load_config(robot="dyros-jet")
    designs = dict(CONFIGS)
    for r in [float(a) for a in sys.argv[1:]] or [None]:
        ours = {k: dict(v) for k, v in OURS.items()}
        if r is not None:
            ours["controller"]["r_input"] = r
        label = base.controller.r_input if r is None else r
        designs[f"ours (R = {label:g})"] = ours
    for state, (angles, support) in postures().items():
        robot = settled_robot(angles, support)
        links = robot.plant.link_angle_rad
        models = {f: linearise(robot, DT, f) for f in Friction}
        for name, changes in designs.items():
            config = configured(base, changes)
            gain, dob, contact = gains(config, robot, support, links, 0.2)
            cells = []
            for friction, model in models.items():
                lqr = loop_modes(model, closed_loop(model, gain))
                with_dob = loop_modes(model, closed_loop(model, gain, dob))
                cells.append(
                    f"{friction.value}: {lqr.text()} | +DOB 0.2 {with_dob.oscillatory:.4f}"
                )
            print(f"{state:6s} {name:42s} Sm {contact.value:10s} " + "; ".join(cells), flush=True)


if __name__ == "__main__":
    main()
