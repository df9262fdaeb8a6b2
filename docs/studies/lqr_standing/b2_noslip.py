import sys, time, numpy as np, mujoco

sys.path.insert(0, "../tests/sim_backend")
sys.path.insert(0, "..")
from test_humanoid_robot import build_robot, URDF_PATH, READY, K_NM_PER_RAD
from controller.humanoid import HumanoidLegGravity, LegModel, SupportState

urdf = URDF_PATH.read_text()
lm = LegModel(urdf)
tau = HumanoidLegGravity(lm, SupportState.DOUBLE).gravity_torque(READY)
for label, setup in [
    ("default", lambda m: None),
    ("noslip 10", lambda m: setattr(m.opt, "noslip_iterations", 10)),
    (
        "elliptic impratio 100",
        lambda m: (
            setattr(m.opt, "cone", mujoco.mjtCone.mjCONE_ELLIPTIC),
            setattr(m.opt, "impratio", 100.0),
        ),
    ),
]:
    robot, _ = build_robot(urdf, READY, goal_rad=READY + tau / K_NM_PER_RAD)
    p = robot.plant
    setup(p.model)
    y0 = [p.ft_sensor_pose(s)[0][1] for s in (0, 1)]
    t = time.perf_counter()
    robot.advance(3.0)
    wall = time.perf_counter() - t
    y = [p.ft_sensor_pose(s)[0][1] for s in (0, 1)]
    print(
        f"{label:24s} separation change in 3 s {((y[0] - y[1]) - (y0[0] - y0[1])) * 1e3:+.3f} mm  wall {wall:.1f} s  cone {p.model.opt.cone} impratio {p.model.opt.impratio}"
    )
