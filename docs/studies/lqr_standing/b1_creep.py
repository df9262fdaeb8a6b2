"""Do the emulated feet creep under a constant goal (gc goals held, no feedback)?"""

import sys, numpy as np

sys.path.insert(0, "../tests/sim_backend")
sys.path.insert(0, "..")
from test_humanoid_robot import build_robot, URDF_PATH, READY, K_NM_PER_RAD
from controller.humanoid import HumanoidLegGravity, LegModel, SupportState

urdf = URDF_PATH.read_text()
lm = LegModel(urdf)
tau = HumanoidLegGravity(lm, SupportState.DOUBLE).gravity_torque(READY)
robot, _ = build_robot(urdf, READY, goal_rad=READY + tau / K_NM_PER_RAD)
p = robot.plant


def feet():
    out = []
    for s in (0, 1):
        pos, R = p.ft_sensor_pose(s)
        out.append(np.r_[pos[:2] * 1e3, np.degrees(np.arctan2(R[1, 0], R[0, 0])) * 1e3])
    return np.array(out)


f0 = feet()
for t in (0.5, 1, 2, 3, 5):
    robot.advance(t - robot.time_s)
    d = feet() - f0
    fx = [robot.foot_wrench(s)[0] for s in (0, 1)]
    print(
        f"t={t}: left dx,dy [mm], dyaw[mdeg] {np.round(d[0], 3)}  right {np.round(d[1], 3)}  sep change {d[0, 1] - d[1, 1]:+.3f} mm  Fy L/R {fx[0][1]:+.1f}/{fx[1][1]:+.1f} N Fz {fx[0][2]:.0f}/{fx[1][2]:.0f}"
    )
