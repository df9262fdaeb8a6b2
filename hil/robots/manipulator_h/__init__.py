"""ROBOTIS MANIPULATOR-H: a 6-DoF arm of the DYNAMIXEL PRO family (two H54-200-S500-R, two
H54-100-S500-R, two H42-20-S300-R on one RS-485 chain), a fixed-base robot from its published
URDF (hil/data/robots/manipulator_h/, with its NOTICE: source, licence, and the inertias used).
Its model, emulation and checks are any fixed-base robot's (hil/robots/fixed_base/); what is its
own: its built-in configuration (hil/data/manipulator_h.toml), its experiments
(experiments.py) and its comparison (every experiment with every controller that applies: the
LQR's need the link encoders, which the stock arm lacks and the configuration adds)."""

from hil.robots.fixed_base import (
    PAPER_CHOICES,
    FixedBaseEmulation,
    applicable,
    check_fixed_base,
)
from hil.robots.fixed_base.model import fixed_base_links
from hil.robots.manipulator_h.experiments import ARM_HOLD, EXPERIMENTS
from hil.robots.profile import Comparison, RobotProfile
from hil.vocabulary import Robot

COMPARISON = Comparison(
    name=None,
    directory="manipulator-h-comparison",
    title="ROBOTIS MANIPULATOR-H: holding, a push at the tool, a trajectory, contact",
    claims_source="Kim et al., ICRA 2018, Sec. III (predictions for this arm)",
    plan=lambda config, long_runs: [
        (experiment, choice)
        for experiment in EXPERIMENTS
        for choice in applicable(PAPER_CHOICES, config)
    ],
)

PROFILE = RobotProfile(
    robot=Robot.MANIPULATOR_H,
    summary="ROBOTIS MANIPULATOR-H, 6 DoF from its published URDF (arm-hold, arm-push, ...)",
    emulated="emulated MANIPULATOR-H",
    model=fixed_base_links,
    emulation=FixedBaseEmulation(),
    experiments=EXPERIMENTS,
    bench_experiment=ARM_HOLD,
    comparisons=(COMPARISON,),
    check=check_fixed_base,
)
