"""What makes the closed-chain design (the paper's servo (4), Euler) oscillate on the emulated
robot: its loop on the linearised emulated robot standing on both feet, with one physical
effect at a time taken out of the linearisation (never out of the product's plant).

Run from this folder: PYTHONPATH=../../.. python causes.py
"""

import numpy as np

from controller.humanoid import SupportState
from hil.config import load_config
from hil.loop import build_controller, robot_model
from hil.vocabulary import ControllerChoice
from sim_backend.humanoid.linear import Friction, linearise
from tests.support.humanoid_loop import closed_loop, loop_modes, settled_robot
from designs import DT, READY, configured

FIRST_ORDER_CLOSED_CHAIN = {
    "model": {"servo_model": "first-order", "sm_coupling": "closed-chain"},
    "controller": {"discretization": "euler", "r_input": 1.0, "kdist_reference": "per-tick"},
}


def variant(model, gravity=True, contact_time_constant_s=None):
    """Change the MuJoCo model in place for one linearisation; returns the undo."""
    saved = (model.opt.gravity.copy(), model.geom_solref.copy())
    if not gravity:
        model.opt.gravity[:] = 0.0
    if contact_time_constant_s is not None:
        model.geom_solref[:, 0] = contact_time_constant_s

    def undo():
        model.opt.gravity[:], model.geom_solref[:] = saved

    return undo


def main() -> None:
    config = configured(load_config(robot="dyros-jet"), FIRST_ORDER_CLOSED_CHAIN)
    robot = settled_robot(READY, SupportState.DOUBLE)
    links = robot.plant.link_angle_rad
    model = robot_model(config)
    contact = model.lqr_contacts([SupportState.DOUBLE])[0]
    choice = ControllerChoice("gc+lqr", 0.2)
    gain = build_controller(config, choice, DT, model, links, contact).lqr_gain
    mujoco_model = robot.plant.model
    cases = [
        ("as emulated", {}),
        ("no gravity in the linearisation", {"gravity": False}),
        ("contacts 5x stiffer (solref 4 ms)", {"contact_time_constant_s": 0.004}),
    ]
    print("closed-chain design (servo (4), Euler) on the linearised emulated robot, two feet:")
    for name, change in cases:
        undo = variant(mujoco_model, **change)
        try:
            cells = []
            for friction in Friction:
                tick = linearise(robot, DT, friction)
                cells.append(
                    f"friction {friction.value}: {loop_modes(tick, closed_loop(tick, gain)).text()}"
                )
        finally:
            undo()
        print(f"  {name:36s} " + "; ".join(cells))
    # the plant itself, without the LQR (the gravity compensator's goals held)
    from controller import TrackingGain

    zero = TrackingGain(np.zeros((12, 12)), np.zeros((12, 36)), DT, float("nan"))
    print("the plant alone (goals held), its least damped oscillatory modes:")
    for friction in Friction:
        tick = linearise(robot, DT, friction)
        eigenvalues = np.linalg.eigvals(tick.f)
        hz = np.angle(eigenvalues) / (2 * np.pi * DT)
        zeta = -np.log(np.abs(eigenvalues)) / np.hypot(
            np.log(np.abs(eigenvalues)), np.angle(eigenvalues)
        )
        keep = (hz > 0.2) & (hz < 12)
        order = np.argsort(zeta[keep])[:4]
        pairs = ", ".join(f"{hz[keep][i]:.2f} Hz (zeta {zeta[keep][i]:.3f})" for i in order)
        print(
            f"  friction {friction.value}: {pairs}; with zero gain {loop_modes(tick, closed_loop(tick, zero)).text()}"
        )
    # the controller's model of the same robot: rigid soles (Sm of (19)), the servo cascade
    import scipy.linalg

    from controller.closed_chain import chain_coordinates, motion_subspace
    from controller.servo_cascade import cascade_state_space
    from hil.controllers.paper_factory import joint_params, servo_cascade

    base = load_config(robot="dyros-jet")
    sm = robot_model(base).sm(links, contact)
    basis = motion_subspace(sm)
    rigid = chain_coordinates(
        cascade_state_space(joint_params(base), servo_cascade(base), sm), basis, 24
    )
    eigenvalues = np.linalg.eigvals(scipy.linalg.expm(rigid.a * DT))
    hz = np.angle(eigenvalues) / (2 * np.pi * DT)
    zeta = -np.log(np.abs(eigenvalues)) / np.hypot(
        np.log(np.abs(eigenvalues)), np.angle(eigenvalues)
    )
    keep = (hz > 0.2) & (hz < 12)
    pairs = ", ".join(
        f"{f:.2f} Hz (zeta {z:.3f})" for f, z in sorted(zip(hz[keep], zeta[keep], strict=True))
    )
    print(
        f"the controller's model (rigid soles, servo cascade), all its modes below 12 Hz: {pairs}"
    )


if __name__ == "__main__":
    main()
