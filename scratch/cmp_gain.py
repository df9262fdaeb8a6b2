import numpy as np
from hil.config import load_config
from hil.loop.robot_model import robot_model
from hil.loop.controller_factory import joint_params
from controller.lqr import design_discrete_tracking_lqr
from controller import LqrWeights
from controller.humanoid import WALKING_READY_LEG_ANGLES_RAD, SupportState

cfg = load_config(robot="dyros-jet")
robot = robot_model(cfg)
sm = robot.sm(np.asarray(WALKING_READY_LEG_ANGLES_RAD), SupportState.DOUBLE)
print(np.round(np.diag(sm), 2), np.abs(sm - np.diag(np.diag(sm))).max())
p = joint_params(cfg)
for m in ("euler",):
    a = design_discrete_tracking_lqr(p, sm, 0.005, LqrWeights(), m, "full")
    b = design_discrete_tracking_lqr(p, sm, 0.005, LqrWeights(), m, "diagonal")
    print(
        np.abs(a.error_gain - b.error_gain).max(),
        np.abs(a.state_increment_gain - b.state_increment_gain).max(),
        a.spectral_radius,
        b.spectral_radius,
    )
    print(np.round(np.diag(a.error_gain), 3))
    print(np.round(np.diag(b.error_gain), 3))
