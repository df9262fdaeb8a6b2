"""The 200 Hz loop: clocks, the phases of a run, the start gate, re-homing, every exit path.

clock.py               lock-step and wall clocks on a fixed grid
timeline.py            the phases of a run by tick (hold, homing, experiment, stop)
spine.py               every loop's spine: bus, supervisor, torque, record (begin_cycle,
                       cycle_actuation, end_cycle) and the common part of every exit path
torque.py              the actuators' torque: on, off when latched (retried), the exit state
run_record.py          the tick's log rows kept and written, the supervisor's news logged
start_gate.py          tick 0: refuse to start, or the sample to start from
homing.py              the slow re-homing after a fault
experiment_feed.py     what the experiment hands the loop: timeline, reference ring, open-loop
                       goals, the LQR's contact
gain_scheduler.py      the LQR gain rescheduled with posture and support, off the 200 Hz path
request.py             what a run is asked to do; Ctrl-C / SIGTERM
runner.py              one experiment's run on the spine (`Loop`, `run_experiment`)
"""

from hil.controllers.paper_factory import build_controller, joint_params
from hil.controllers.robot_model import RobotModel, robot_model
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
    "LockstepClock",
    "Loop",
    "LoopClock",
    "Phase",
    "RobotModel",
    "RunRequest",
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
