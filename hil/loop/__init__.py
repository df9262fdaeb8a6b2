"""The 200 Hz loop: clocks, the phases of a run, the start gate, re-homing, every exit path.

clock.py               lock-step and wall clocks on a fixed grid
timeline.py            the phases of a run by tick (hold, homing, experiment, stop)
start_gate.py          tick 0: refuse to start, or the sample to start from
homing.py              the slow re-homing after a fault
robot_model.py         the controller's model of the robot (single links, DYROS-JET's legs)
gain_scheduler.py      the LQR gain rescheduled with posture and support, off the 200 Hz path
controller_factory.py  the configured robot model + a controller choice -> a controller
request.py             what a run is asked to do; Ctrl-C / SIGTERM
runner.py              the loop itself (`Loop`, `run_experiment`): each tick, tick 0
experiment_feed.py     what the experiment hands the loop: the reference ring, the phase's settings
run_record.py          the tick's log rows kept and written, the supervisor's news logged
run_end.py             every exit path: torque state, bus closed, metrics, summary.json
"""

from hil.controllers.paper_factory import build_controller, joint_params
from hil.controllers.robot_model import HumanoidLegs, RobotModel, SingleLinks, robot_model
from hil.loop.clock import LockstepClock, LoopClock, Tick, WallClock
from hil.loop.homing import HomingPlan, plan_homing
from hil.loop.request import MAX_RUN_DURATION_S, RunRequest, StopFlag, duration_problem
from hil.loop.runner import LOST_BUS_ERRORS, Loop, run_experiment
from hil.loop.start_gate import StartRefused
from hil.loop.timeline import Phase, Timeline

__all__ = [
    "LOST_BUS_ERRORS",
    "MAX_RUN_DURATION_S",
    "HomingPlan",
    "HumanoidLegs",
    "LockstepClock",
    "Loop",
    "LoopClock",
    "Phase",
    "RobotModel",
    "RunRequest",
    "SingleLinks",
    "StartRefused",
    "StopFlag",
    "Tick",
    "Timeline",
    "WallClock",
    "build_controller",
    "duration_problem",
    "joint_params",
    "plan_homing",
    "robot_model",
    "run_experiment",
]
