"""DYROS-JET (Kim et al., ICRA 2018, Sec. IV-C): the humanoid's 12 leg joints, H54-200-S500-R
actuators with link encoders on CAN and a six-axis force/torque sensor under each ankle, the
whole robot from its URDF (hil/data/robots/dyros_jet.urdf). Its facts (the leg joints' names
and order, the upper body's locked posture) live once on each side of the product, which may
not import each other: controller/humanoid/leg_model.py (the controller's model) and
sim_backend/humanoid/params.py (the emulator's truth); tests/hil/test_dyros_jet_facts.py keeps
them equal to each other and to this robot's configuration, hil/data/dyros_jet.toml."""

from hil.experiments import (
    PUSH,
    STAND,
    STEP_ON_OBJECT,
    SUSPENDED_CHIRP,
    WALK_DYNAMIC,
    WALK_SLOW,
)
from hil.robots.dyros_jet.check import check_description
from hil.robots.dyros_jet.comparison import STANDING_COMPARISON, WALKING_COMPARISON
from hil.robots.dyros_jet.emulation import HumanoidEmulation
from hil.robots.dyros_jet.model import humanoid_legs
from hil.robots.profile import RobotProfile
from hil.vocabulary import Robot

PROFILE = RobotProfile(
    robot=Robot.DYROS_JET,
    summary="the humanoid DYROS-JET's 12 leg joints (stand, push, the walks; Sec. IV-C)"
    " and hung for its twin (suspended-chirp)",
    emulated="emulated DYROS-JET legs",
    model=humanoid_legs,
    emulation=HumanoidEmulation(),
    experiments=(STAND, PUSH, WALK_SLOW, WALK_DYNAMIC, STEP_ON_OBJECT, SUSPENDED_CHIRP),
    bench_experiment=STAND,
    comparisons=(STANDING_COMPARISON, WALKING_COMPARISON),
    check=check_description,
)
