import sys, time
from pathlib import Path
import numpy as np
from hil.config import load_config
from hil.session import Session, Setup
from hil.experiments import get_experiment
from hil.experiments.humanoid import StandingKinematics
from hil.output.rundir import load_run
from hil.vocabulary import ControllerChoice, ControllerKind
import os

if os.environ.get("LQR_COUPLING"):
    # study only: run the LQR design named by LQR_COUPLING on the configured Sm (the lead wires it)
    import hil.loop.robot_model as rm

    _init = rm.HumanoidLegs.__init__

    def _patched(self, *a, **k):
        _init(self, *a, **k)
        self.lqr_coupling = os.environ["LQR_COUPLING"]

    rm.HumanoidLegs.__init__ = _patched
if os.environ.get("STICKY"):
    # study only: the emulator with sticking soles (ContactParams.sticking())
    import dataclasses
    import sim_backend.humanoid.robot as hr
    from sim_backend.humanoid.params import ContactParams, RobotTruthParams

    _rinit = hr.EmulatedRobot.__init__

    def _sticky(self, *a, truth=None, **k):
        truth = dataclasses.replace(truth or RobotTruthParams(), contact=ContactParams.sticking())
        _rinit(self, *a, truth=truth, **k)

    hr.EmulatedRobot.__init__ = _sticky
cfg = load_config(os.environ["CFG"]) if os.environ.get("CFG") else load_config(robot="dyros-jet")
exp = get_experiment(sys.argv[1] if len(sys.argv) > 1 else "stand")
kind = ControllerKind(sys.argv[2] if len(sys.argv) > 2 else "pid")
dur = float(sys.argv[3]) if len(sys.argv) > 3 else 3.0
kd = float(sys.argv[4]) if len(sys.argv) > 4 else 0.2
s = Session(cfg, Setup.IN_PROCESS, out_root=Path("/tmp/lqrstudy/runs"), plots=False, quiet=True)
t = time.perf_counter()
r = s.run_one(exp, ControllerChoice(kind, kd), print_result=False, duration_s=dur)
print(r.ending, round(time.perf_counter() - t, 2), r.metrics, r.out_dir)
run = load_run(r.out_dir)
k = StandingKinematics.of(run)
print("desired", exp._desired_zmp(), "polygon", k.support_polygon)
for i in range(0, len(run.time_s), max(1, len(run.time_s) // 10)):
    print(round(run.time_s[i], 3), k.zmp_m[i], round(k.vertical_n[i], 1), round(k.tilt_rad[i], 4))
