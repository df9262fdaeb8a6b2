import time, numpy as np
from hil.config import load_config
from hil.loop.robot_model import robot_model
from hil.loop.controller_factory import build_controller
from hil.vocabulary import ControllerChoice, ControllerKind
from controller.humanoid import WALKING_READY_LEG_ANGLES_RAD, SupportState

cfg = load_config(robot="dyros-jet")
robot = robot_model(cfg)
q = np.asarray(WALKING_READY_LEG_ANGLES_RAD)
t = time.perf_counter()
for _ in range(5):
    sm = robot.sm(q, SupportState.DOUBLE)
print("sm", (time.perf_counter() - t) / 5)
from hil.experiments import get_experiment
from hil.loop.controller_factory import build_controller
import inspect

print(inspect.signature(build_controller))
c = build_controller(
    cfg,
    ControllerChoice(ControllerKind.GC_LQR_DOB),
    cfg.loop.period_s,
    robot,
    q,
    SupportState.DOUBLE,
)
import cProfile, pstats

t = time.perf_counter()
for _ in range(5):
    c.params.design_gain(sm, cfg.loop.period_s)
print("design", (time.perf_counter() - t) / 5)
cProfile.run("for _ in range(5): c.params.design_gain(sm, cfg.loop.period_s)", "/tmp/hum/prof")
pstats.Stats("/tmp/hum/prof").sort_stats("cumtime").print_stats(15)
