"""The paper's 1-DoF testbed (Kim et al., ICRA 2018, Sec. IV-B, Fig. 4a): an H54-200-S500-R
driving a link with a load through its elastic gear, a link encoder on CAN, a block with a force
sensor. Several joints in one configuration are independent copies of it."""

from hil.experiments import CONTACT, CONTACT_LONG, IDENTIFY, IMPACT, IMPACT_LONG
from hil.robots.profile import RobotProfile
from hil.robots.testbed.comparison import TESTBED_COMPARISON
from hil.robots.testbed.emulation import TestbedEmulation
from hil.robots.testbed.model import single_links
from hil.vocabulary import Robot

PROFILE = RobotProfile(
    robot=Robot.TESTBED,
    summary="the paper's 1-DoF testbed (contact, impact; Figs. 5 and 6)",
    emulated="emulated testbed",
    model=single_links,
    emulation=TestbedEmulation(),
    experiments=(CONTACT, IMPACT, CONTACT_LONG, IMPACT_LONG, IDENTIFY),
    bench_experiment=IMPACT,
    comparisons=(TESTBED_COMPARISON,),
)
