"""The DYNAMIXEL PRO family as the driver knows it: per model, its number, its control-table
layout and the figures the driver converts and checks with. One table, one row a model.

Written from the ROBOTIS e-Manual on the driver's side of the wire (the emulator has its own
table, sim_backend/dynamixel/models.py, written from the same pages; a test compares them):
each row's figures come from its model's page, https://emanual.robotis.com/docs/en/dxl/pro/<model>/
(the "(A)" revisions: .../pro/<model>a/) or .../dxl/p/<model>/ for the DYNAMIXEL-P:
- model number: the page's "Model Number(0)" table;
- resolution [pulse/rev]: the specification table; the position-mode range (+-pulses): the
  Goal Position(596) include (PRO) or the Max/Min Position Limit range (PRO+);
- velocity unit [rev/min]: the Goal Velocity(600) include's scale factor (PRO), 0.01 (PRO+);
- current unit [A]: the Goal Torque(604) include, "PRO 54" 33,000 / 2,048 mA and "PRO 42"
  8,250 / 2,048 mA (PRO; the L54s taken as "PRO 54"), 1 mA (PRO+);
- current cap: the top of Torque Limit(30)'s range (PRO) or Current Limit(38)'s (PRO+) in the
  model's unit; where the range was not read, 3 x the initial value, the ratio of the three
  PRO pages read (H54-200-S500-R 620 / 1860, H42-20-S300-R 465 / 1395, M54-40-S250-R 120 / 360):
  `ASSUMED_CURRENT_CAPS` lists those models;
- continuous torque [N m] and current [A]: the specification table ("calculated from the core
  motor's specification"); their ratio is the torque constant of the driver's torque ESTIMATE.

The legacy pages' initial values other than the H54-200-S500-R's, H42-20-S300-R's and
M54-40-S250-R's were read through nim65s/dmx-rs (generated from the same markdown), which
agrees with every figure read on the pages themselves. docs/actuators.md tabulates the family.

A model not here is refused with the reason (`REFUSED`, or "unknown").
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType


class Layout(enum.Enum):
    """The control-table layout a model's firmware has."""

    PRO = "PRO"  # legacy: Torque Enable 562, Goal Position 596, Present Position 611
    PRO_PLUS = "PRO+"  # PRO(A) and DYNAMIXEL-P: Torque Enable 512, Goal Position 564, 580


@dataclass(frozen=True)
class ActuatorModel:
    """One model's row (see the module docstring for the source of each figure)."""

    name: str
    number: int
    layout: Layout
    pulses_per_rev: int
    position_limit_pulses: int
    velocity_unit_rpm: float
    current_unit_a: float
    current_cap_raw: int
    continuous_torque_nm: float
    continuous_current_a: float

    @property
    def page(self) -> str:
        """The model's e-Manual page."""
        series = "p" if self.name.startswith("P") else "pro"
        slug = self.name.lower().replace("(a)", "a")
        return f"https://emanual.robotis.com/docs/en/dxl/{series}/{slug}/"


PRO, PRO_PLUS = Layout.PRO, Layout.PRO_PLUS
_54 = 33.0 / 2048.0  # A per unit, "PRO 54" (16.11328 mA)
_42 = 8.25 / 2048.0  # A per unit, "PRO 42" (4.02832 mA)
_MA = 0.001  # PRO+: 1 mA
_R = 0.01  # PRO+: 0.01 rev/min

_m = ActuatorModel
# fmt: off
#   name                number  layout   pulse/rev  +-pulses  rev/min/unit A/unit  cap   N m  A
_ROWS = (
    _m("H54-200-S500-R",    54024, PRO,      501_923, 250_961, 0.00199234, _54,  1860, 44.7, 9.3),
    _m("H54-100-S500-R",    53768, PRO,      501_923, 250_961, 0.00199234, _54,   930, 25.3, 5.5),
    _m("H42-20-S300-R",     51200, PRO,      303_750, 151_875, 0.00329218, _42,  1395,  5.1, 1.5),
    _m("M54-60-S250-R",     46352, PRO,      251_417, 125_708, 0.00397746, _54,   540, 10.1, 3.0),
    _m("M54-40-S250-R",     46096, PRO,      251_417, 125_708, 0.00397746, _54,   360,  3.9, 1.9),
    _m("M42-10-S260-R",     43288, PRO,      263_187, 131_593, 0.00389076, _42,   900,  1.7, 0.6),
    _m("L54-50-S500-R",     38152, PRO,      361_384, 180_692, 0.00199234, _54,   360, 14.0, 1.9),
    _m("L54-50-S290-R",     38176, PRO,      207_692, 103_846, 0.00346667, _54,   360,  4.8, 1.9),
    _m("L54-30-S500-R",     37896, PRO,      361_384, 180_692, 0.00199234, _54,   300,  5.4, 1.6),
    _m("L54-30-S400-R",     37928, PRO,      288_395, 144_197, 0.00249657, _54,   300,  2.5, 1.6),
    _m("H54-200-S500-R(A)", 54025, PRO_PLUS, 1_003_846, 501_923, _R, _MA, 22_740, 44.7, 9.3),
    _m("H54-100-S500-R(A)", 53769, PRO_PLUS, 1_003_846, 501_923, _R, _MA, 15_900, 25.3, 5.5),
    _m("H42-20-S300-R(A)",  51201, PRO_PLUS,   607_500, 303_750, _R, _MA,  4_500,  5.1, 1.5),
    _m("M54-60-S250-R(A)",  46353, PRO_PLUS,   502_834, 251_417, _R, _MA,  7_980, 10.1, 3.0),
    _m("M54-40-S250-R(A)",  46097, PRO_PLUS,   502_834, 251_417, _R, _MA,  4_470,  3.9, 1.9),
    _m("M42-10-S260-R(A)",  43289, PRO_PLUS,   526_375, 263_187, _R, _MA,  1_461,  1.7, 0.6),
    _m("PH54-200-S500-R",    2020, PRO_PLUS, 1_003_846, 501_923, _R, _MA, 22_740, 44.7, 9.3),
    _m("PH54-100-S500-R",    2010, PRO_PLUS, 1_003_846, 501_923, _R, _MA, 15_900, 25.3, 5.5),
    _m("PH42-020-S300-R",    2000, PRO_PLUS,   607_500, 303_750, _R, _MA,  4_500,  5.1, 1.5),
    _m("PM54-060-S250-R",    2120, PRO_PLUS,   502_834, 251_417, _R, _MA,  7_980, 10.1, 3.0),
    _m("PM54-040-S250-R",    2110, PRO_PLUS,   502_834, 251_417, _R, _MA,  4_470,  3.9, 1.9),
    _m("PM42-010-S260-R",    2100, PRO_PLUS,   526_374, 263_187, _R, _MA,  1_461,  1.7, 0.6),
)
# fmt: on

ACTUATOR_MODELS: Mapping[int, ActuatorModel] = MappingProxyType({m.number: m for m in _ROWS})

# Current caps not read from the page (see the module docstring).
ASSUMED_CURRENT_CAPS: frozenset[str] = frozenset(
    {
        "H54-100-S500-R",
        "M54-60-S250-R",
        "M42-10-S260-R",
        "L54-50-S500-R",
        "L54-50-S290-R",
        "L54-30-S500-R",
        "L54-30-S400-R",
    }
)

# Models of the family the driver does not drive, and why: number -> (name, reason).
REFUSED: Mapping[int, tuple[str, str]] = MappingProxyType(
    {
        35072: (
            "L42-10-S300-R",
            "its control table is not the PRO layout (e-Manual l42-10-s300-r: Position PID gains "
            "at 590..594, no velocity PI gains, Goal Position 0 ~ 4,095, Goal Torque in 0.1 % "
            "of the maximum torque rather than a current)",
        ),
    }
)
