"""Your own fixed-base robot of flexible joints, from its URDF and the configuration file
(`[model] robot = "fixed-base"`, `description`): the controller's model in pinocchio
(model.py), its emulation (emulation.py: sim_backend/fixed_base/), the checks of the
configuration against its URDF (check.py). Its built-in configuration, hil/data/fixed_base.toml,
is a two-link arm to start from (`hil config --robot fixed-base`)."""

from collections.abc import Sequence

from hil.config import Config
from hil.experiments.arm import HoldExperiment
from hil.robots.fixed_base.check import check_fixed_base
from hil.robots.fixed_base.emulation import FixedBaseEmulation
from hil.robots.fixed_base.model import fixed_base_links
from hil.robots.profile import Comparison, RobotProfile
from hil.vocabulary import ControllerChoice, ControllerKind, Robot

__all__ = ["PAPER_CHOICES", "PROFILE", "FixedBaseEmulation", "applicable", "check_fixed_base"]


def applicable(choices: Sequence[ControllerChoice], config: Config) -> tuple[ControllerChoice, ...]:
    """The controllers that can run on this robot: without link encoders, those that need no
    link angle (hil.controllers.choice.link_angle_refusal says why the others cannot)."""
    bare = config.joints_without_link_encoder
    return tuple(c for c in choices if not (bare and c.ref.needs_link_angle))


HOLD = HoldExperiment(
    name="hold",
    title="The robot holds every joint at 0 against gravity",
    duration_s=5.0,
    start_rad=0.0,
)
# the paper's four controllers, each a fixed-base robot's comparison runs where it applies
PAPER_CHOICES = (
    ControllerChoice(ControllerKind.PID),
    ControllerChoice(ControllerKind.GC),
    ControllerChoice(ControllerKind.GC_LQR),
    ControllerChoice(ControllerKind.GC_LQR_DOB, 1.0),
)
HOLD_COMPARISON = Comparison(
    name=None,
    directory="fixed-base-comparison",
    title="Your robot holding its zero pose: Kim et al., ICRA 2018, (5)-(8), (25)",
    claims_source="Kim et al., ICRA 2018, Sec. III",
    plan=lambda config, long_runs: [(HOLD, choice) for choice in applicable(PAPER_CHOICES, config)],
)

PROFILE = RobotProfile(
    robot=Robot.FIXED_BASE,
    summary="your own fixed-base robot from its URDF (hil config --robot fixed-base)",
    emulated="emulated fixed-base robot",
    model=fixed_base_links,
    emulation=FixedBaseEmulation(),
    experiments=(HOLD,),
    bench_experiment=HOLD,
    comparisons=(HOLD_COMPARISON,),
    check=check_fixed_base,
)
