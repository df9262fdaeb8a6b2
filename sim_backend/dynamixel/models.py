"""The DYNAMIXEL PRO family as the emulator serves it: one entry per model, figures with sources.

Every model ROBOTIS publish a Protocol 2.0 control table for, in three firmwares
(`Firmware`): the legacy PRO (Torque Enable 562, Goal Position 596), the advanced PRO(A) of
the "(A)" revisions (Torque Enable 512, Goal Position 564, twice the resolution, 1 mA and
0.01 rev/min units) and the DYNAMIXEL-P (PRO+), whose table is the PRO(A)'s plus Protocol
Type (13). `control_table.py` builds each model's items from these figures.

Source of every figure unless its comment says otherwise: the model's ROBOTIS e-Manual page
(`ModelFigures.page`; markdown in ROBOTIS-GIT/emanual, docs/en/dxl/pro/*.md and
docs/en/dxl/p/*.md), its "Control Table of EEPROM/RAM Area" (initial value, range) and the
includes it pulls in; resolution, gear ratio and continuous torque/current from the
specification data (_data/dxl_pro_info.yml, dxl_proa_info.yml, dxl_p_info.yml). Where the page
prints "-" for an initial value or was not read, the figure is an assumption and
`ModelFigures.assumed` says which and why. The legacy pages' initial values other than the
H54-200-S500-R's, H42-20-S300-R's and M54-40-S250-R's were read through nim65s/dmx-rs
(generated from the same markdown), which agrees with every figure read on the pages
themselves. docs/actuators.md tabulates the family. The driver's tables
(drivers/dynamixel/models.py) are written from the same pages on their own;
tests/sim_backend/test_family_tables.py compares the two, so that a typo on either side shows.

Not emulated, refused with the reason (`REFUSED`): the L42-10-S300-R, whose table is not the
PRO layout.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

EMANUAL = "https://emanual.robotis.com/docs/en/dxl/"
INT32_MAX = 2**31 - 1


class Firmware(enum.Enum):
    """Which control-table layout a model's firmware has."""

    PRO = "PRO"
    PRO_A = "PRO(A)"
    P = "P"

    @property
    def pro_plus(self) -> bool:
        """The PRO(A) / P table (Torque Enable 512); False for the legacy PRO (562)."""
        return self is not Firmware.PRO


@dataclass(frozen=True)
class Gains:
    """The servo's gain registers' initial values (PRO: 586/588/594; PRO+: 524/526/532)."""

    velocity_i: int
    velocity_p: int
    position_p: int


@dataclass(frozen=True)
class DeviceUnits:
    """A model's control-table units in SI (the emulator's one place for them)."""

    pulses_per_rev: int
    velocity_unit_rpm: float
    current_unit_a: float

    @property
    def rad_per_pulse(self) -> float:
        return 2.0 * math.pi / self.pulses_per_rev

    @property
    def rad_s_per_velocity_unit(self) -> float:
        return self.velocity_unit_rpm * 2.0 * math.pi / 60.0

    @property
    def ampere_per_current_unit(self) -> float:
        return self.current_unit_a


@dataclass(frozen=True)
class ModelFigures:
    """One model: identity, units, the initial values and ranges that differ between models.

    position_limit: the position-mode range, +-pulses (Goal Position include / the PRO+
        "Max/Min Position Limit" range): also the Max/Min Position Limit range on PRO+.
    max_position: Max Position Limit's initial value (Min Position Limit's is its negative).
    current_limit / current_limit_max: Torque Limit(30) (PRO) or Current Limit(38) (PRO+),
        initial value and the top of its range, in the model's current unit.
    velocity_limit / velocity_limit_max: Velocity Limit(32 / 44), initial and range top.
    acceleration_limit / acceleration_limit_max: Acceleration Limit(26 / 40).
    continuous_torque_nm / continuous_current_a / gear_ratio: the specification table's
        ("calculated from the core motor's specification", e-Manual).
    assumed: field -> why it is an assumption (the page prints "-" or was not read).
    """

    name: str
    number: int
    firmware: Firmware
    page: str
    pulses_per_rev: int
    position_limit: int
    max_position: int
    velocity_unit_rpm: float
    current_unit_a: float
    current_limit: int
    current_limit_max: int
    velocity_limit: int
    velocity_limit_max: int
    acceleration_limit: int
    acceleration_limit_max: int
    moving_threshold: int
    shutdown: int
    max_voltage_limit: int
    gains: Gains
    continuous_torque_nm: float
    continuous_current_a: float
    gear_ratio: float
    assumed: Mapping[str, str] = field(default_factory=dict)

    @property
    def units(self) -> DeviceUnits:
        return DeviceUnits(self.pulses_per_rev, self.velocity_unit_rpm, self.current_unit_a)


# Units shared by a frame size (e-Manual includes control_table_600_goalvelocity_pro.md,
# control_table_604_goaltorque_pro.md; PRO+: the "Unit" column of every PRO(A)/P table).
PRO54_CURRENT_A = 33.0 / 2048.0  # "PRO 54": mA = value x 33,000 / 2,048 = 16.11328 mA
PRO42_CURRENT_A = 8.25 / 2048.0  # "PRO 42": mA = value x 8,250 / 2,048 = 4.02832 mA
PRO_PLUS_CURRENT_A = 0.001  # 1 [mA]
PRO_PLUS_VELOCITY_RPM = 0.01  # 0.01 [rev/min]

# Legacy PRO: the three pages whose Torque Limit range was read give 3 x the initial value
# (H54-200 620 / 0~1860, H42-20 465 / 0~1395, M54-40 120 / 0~360); the others are assumed so.
_TORQUE_LIMIT_RANGE_ASSUMED = (
    "Torque Limit range not read: 3 x the initial, as on H54-200/H42/M54-40"
)
# Legacy PRO Acceleration Limit: "-" on every page but the H42's (255): 255 assumed, the H42's.
_ACCELERATION_ASSUMED = "Acceleration Limit initial '-' on the page: 255 assumed (the H42-20's)"
_PRO_PLUS_GAINS_ASSUMED = (
    "gain initial values '-' on the page: assumed the PH54-200-S500-R's published 2209/6153/314"
)


def _pro(
    name: str,
    number: int,
    *,
    pulses_per_rev: int,
    position_limit: int,
    velocity_unit_rpm: float,
    current_unit_a: float,
    torque_limit: int,
    torque_limit_max: int,
    velocity_limit: int,
    gains: Gains,
    torque_nm: float,
    current_a: float,
    gear_ratio: float,
    acceleration_limit: int = 255,
    assumed: Mapping[str, str] | None = None,
) -> ModelFigures:
    """A legacy PRO model: what its pages share (Moving Threshold 50, Shutdown 58, Max Voltage
    Limit 400, ranges to INT32_MAX) around what they do not."""
    return ModelFigures(
        name=name,
        number=number,
        firmware=Firmware.PRO,
        page=f"{EMANUAL}pro/{name.lower()}/",
        pulses_per_rev=pulses_per_rev,
        position_limit=position_limit,
        max_position=position_limit,
        velocity_unit_rpm=velocity_unit_rpm,
        current_unit_a=current_unit_a,
        current_limit=torque_limit,
        current_limit_max=torque_limit_max,
        velocity_limit=velocity_limit,
        velocity_limit_max=INT32_MAX,
        acceleration_limit=acceleration_limit,
        acceleration_limit_max=INT32_MAX,
        moving_threshold=50,
        shutdown=58,
        max_voltage_limit=400,
        gains=gains,
        continuous_torque_nm=torque_nm,
        continuous_current_a=current_a,
        gear_ratio=gear_ratio,
        assumed=MappingProxyType(dict(assumed or {})),
    )


def _pro_plus(
    name: str,
    number: int,
    firmware: Firmware,
    *,
    page: str,
    pulses_per_rev: int,
    position_limit: int,
    max_position: int,
    current_limit: int,
    velocity_limit: int,
    acceleration_limit: int,
    acceleration_limit_max: int,
    torque_nm: float,
    current_a: float,
    gear_ratio: float,
    moving_threshold: int = 20,
    shutdown: int = 58,
    max_voltage_limit: int = 350,
    gains: Gains = Gains(2209, 6153, 314),
    assumed: Mapping[str, str] | None = None,
) -> ModelFigures:
    """A PRO(A) or P model: Current Limit and Velocity Limit top out at their initial values
    (every page read: "0 ~ initial"), units 1 mA and 0.01 rev/min."""
    notes = dict(assumed or {})
    if gains == Gains(2209, 6153, 314) and name != "PH54-200-S500-R":
        notes.setdefault("gains", _PRO_PLUS_GAINS_ASSUMED)
    return ModelFigures(
        name=name,
        number=number,
        firmware=firmware,
        page=page,
        pulses_per_rev=pulses_per_rev,
        position_limit=position_limit,
        max_position=max_position,
        velocity_unit_rpm=PRO_PLUS_VELOCITY_RPM,
        current_unit_a=PRO_PLUS_CURRENT_A,
        current_limit=current_limit,
        current_limit_max=current_limit,
        velocity_limit=velocity_limit,
        velocity_limit_max=velocity_limit,
        acceleration_limit=acceleration_limit,
        acceleration_limit_max=acceleration_limit_max,
        moving_threshold=moving_threshold,
        shutdown=shutdown,
        max_voltage_limit=max_voltage_limit,
        gains=gains,
        continuous_torque_nm=torque_nm,
        continuous_current_a=current_a,
        gear_ratio=gear_ratio,
        assumed=MappingProxyType(notes),
    )


def _proa_page(name: str) -> str:
    return f"{EMANUAL}pro/{name.lower().replace('(a)', 'a')}/"


def _p_page(name: str) -> str:
    return f"{EMANUAL}p/{name.lower()}/"


# fmt: off
FAMILY: tuple[ModelFigures, ...] = (
    # --- legacy PRO (Goal Position 596). Units: Goal Velocity(600) include (scale factor),
    # Goal Torque(604) include (PRO 54 / PRO 42); ranges: Goal Position(596) and
    # Min/Max Position Limit(36, 40) includes; gains: the table's initial values.
    _pro("H54-200-S500-R", 54024, pulses_per_rev=501_923, position_limit=250_961,
         velocity_unit_rpm=0.00199234, current_unit_a=PRO54_CURRENT_A,
         torque_limit=620, torque_limit_max=1860, velocity_limit=17_000,
         gains=Gains(14, 399, 32), torque_nm=44.7, current_a=9.3, gear_ratio=501.923,
         assumed={"acceleration_limit": _ACCELERATION_ASSUMED}),
    _pro("H54-100-S500-R", 53768, pulses_per_rev=501_923, position_limit=250_961,
         velocity_unit_rpm=0.00199234, current_unit_a=PRO54_CURRENT_A,
         torque_limit=310, torque_limit_max=930, velocity_limit=17_000,
         gains=Gains(16, 256, 32), torque_nm=25.3, current_a=5.5, gear_ratio=501.923,
         assumed={"acceleration_limit": _ACCELERATION_ASSUMED,
                  "current_limit_max": _TORQUE_LIMIT_RANGE_ASSUMED}),
    _pro("H42-20-S300-R", 51200, pulses_per_rev=303_750, position_limit=151_875,
         velocity_unit_rpm=0.00329218, current_unit_a=PRO42_CURRENT_A,
         torque_limit=465, torque_limit_max=1395, velocity_limit=10_300,
         gains=Gains(40, 440, 32), torque_nm=5.1, current_a=1.5, gear_ratio=303.75),
    _pro("M54-60-S250-R", 46352, pulses_per_rev=251_417, position_limit=125_708,
         velocity_unit_rpm=0.00397746, current_unit_a=PRO54_CURRENT_A,
         torque_limit=180, torque_limit_max=540, velocity_limit=8_000,
         gains=Gains(16, 256, 32), torque_nm=10.1, current_a=3.0, gear_ratio=251.4,
         assumed={"acceleration_limit": _ACCELERATION_ASSUMED,
                  "current_limit_max": _TORQUE_LIMIT_RANGE_ASSUMED}),
    _pro("M54-40-S250-R", 46096, pulses_per_rev=251_417, position_limit=125_708,
         velocity_unit_rpm=0.00397746, current_unit_a=PRO54_CURRENT_A,
         torque_limit=120, torque_limit_max=360, velocity_limit=8_000,
         gains=Gains(16, 256, 32), torque_nm=3.9, current_a=1.9, gear_ratio=251.4,
         assumed={"acceleration_limit": _ACCELERATION_ASSUMED}),
    _pro("M42-10-S260-R", 43288, pulses_per_rev=263_187, position_limit=131_593,
         velocity_unit_rpm=0.00389076, current_unit_a=PRO42_CURRENT_A,
         torque_limit=300, torque_limit_max=900, velocity_limit=8_000,
         gains=Gains(72, 520, 32), torque_nm=1.7, current_a=0.6, gear_ratio=257.0,
         assumed={"acceleration_limit": _ACCELERATION_ASSUMED,
                  "current_limit_max": _TORQUE_LIMIT_RANGE_ASSUMED}),
    # L54: the Goal Torque include's "PRO 54" formula is taken to cover the 54 mm L models
    _pro("L54-50-S500-R", 38152, pulses_per_rev=361_384, position_limit=180_692,
         velocity_unit_rpm=0.00199234, current_unit_a=PRO54_CURRENT_A,
         torque_limit=120, torque_limit_max=360, velocity_limit=8_000,
         gains=Gains(16, 256, 32), torque_nm=14.0, current_a=1.9, gear_ratio=501.923,
         assumed={"acceleration_limit": _ACCELERATION_ASSUMED,
                  "current_limit_max": _TORQUE_LIMIT_RANGE_ASSUMED}),
    _pro("L54-50-S290-R", 38176, pulses_per_rev=207_692, position_limit=103_846,
         velocity_unit_rpm=0.00346667, current_unit_a=PRO54_CURRENT_A,
         torque_limit=120, torque_limit_max=360, velocity_limit=8_000,
         gains=Gains(16, 412, 250), torque_nm=4.8, current_a=1.9, gear_ratio=288.5,
         assumed={"acceleration_limit": _ACCELERATION_ASSUMED,
                  "current_limit_max": _TORQUE_LIMIT_RANGE_ASSUMED}),
    _pro("L54-30-S500-R", 37896, pulses_per_rev=361_384, position_limit=180_692,
         velocity_unit_rpm=0.00199234, current_unit_a=PRO54_CURRENT_A,
         torque_limit=100, torque_limit_max=300, velocity_limit=9_000,
         gains=Gains(16, 256, 32), torque_nm=5.4, current_a=1.6, gear_ratio=501.923,
         assumed={"acceleration_limit": _ACCELERATION_ASSUMED,
                  "current_limit_max": _TORQUE_LIMIT_RANGE_ASSUMED}),
    _pro("L54-30-S400-R", 37928, pulses_per_rev=288_395, position_limit=144_197,
         velocity_unit_rpm=0.00249657, current_unit_a=PRO54_CURRENT_A,
         torque_limit=100, torque_limit_max=300, velocity_limit=9_000,
         gains=Gains(16, 412, 200), torque_nm=2.5, current_a=1.6, gear_ratio=400.5,
         assumed={"acceleration_limit": _ACCELERATION_ASSUMED,
                  "current_limit_max": _TORQUE_LIMIT_RANGE_ASSUMED}),
    # --- PRO(A) (Goal Position 564): each page's table; Acceleration Limit's range is read
    # only on the H54-200(A) page (0 ~ 3,992,644); the others take their P twin's range.
    _pro_plus("H54-200-S500-R(A)", 54025, Firmware.PRO_A, page=_proa_page("H54-200-S500-R(A)"),
              pulses_per_rev=1_003_846, position_limit=501_923, max_position=501_433,
              current_limit=22_740, velocity_limit=2_900, acceleration_limit=9_982,
              acceleration_limit_max=3_992_644, shutdown=52,
              torque_nm=44.7, current_a=9.3, gear_ratio=501.923),
    _pro_plus("H54-100-S500-R(A)", 53769, Firmware.PRO_A, page=_proa_page("H54-100-S500-R(A)"),
              pulses_per_rev=1_003_846, position_limit=501_923, max_position=501_433,
              current_limit=15_900, velocity_limit=2_920, acceleration_limit=10_639,
              acceleration_limit_max=4_255_632, moving_threshold=50, shutdown=52,
              torque_nm=25.3, current_a=5.5, gear_ratio=501.923,
              assumed={"acceleration_limit_max": "range not read: the PH54-100-S500-R's"}),
    _pro_plus("H42-20-S300-R(A)", 51201, Firmware.PRO_A, page=_proa_page("H42-20-S300-R(A)"),
              pulses_per_rev=607_500, position_limit=303_750, max_position=303_454,
              current_limit=4_500, velocity_limit=2_920, acceleration_limit=10_765,
              acceleration_limit_max=4_306_173, shutdown=52,
              torque_nm=5.1, current_a=1.5, gear_ratio=303.75,
              assumed={"acceleration_limit_max": "range not read: the PH42-020-S300-R's"}),
    _pro_plus("M54-60-S250-R(A)", 46353, Firmware.PRO_A, page=_proa_page("M54-60-S250-R(A)"),
              pulses_per_rev=502_834, position_limit=251_417, max_position=251_173,
              current_limit=7_980, velocity_limit=2_830, acceleration_limit=11_145,
              acceleration_limit_max=4_457_932, moving_threshold=50, shutdown=52,
              torque_nm=10.1, current_a=3.0, gear_ratio=251.4,
              assumed={"acceleration_limit_max": "range not read: the PM54-060-S250-R's"}),
    _pro_plus("M54-40-S250-R(A)", 46097, Firmware.PRO_A, page=_proa_page("M54-40-S250-R(A)"),
              pulses_per_rev=502_834, position_limit=251_417, max_position=251_173,
              current_limit=4_470, velocity_limit=2_840, acceleration_limit=11_037,
              acceleration_limit_max=4_414_976, shutdown=52,
              torque_nm=3.9, current_a=1.9, gear_ratio=251.4,
              assumed={"acceleration_limit_max": "range not read: the PM54-040-S250-R's"}),
    _pro_plus("M42-10-S260-R(A)", 43289, Firmware.PRO_A, page=_proa_page("M42-10-S260-R(A)"),
              pulses_per_rev=526_375, position_limit=263_187, max_position=262_931,
              current_limit=1_461, velocity_limit=2_600, acceleration_limit=10_867,
              acceleration_limit_max=4_346_756, shutdown=52, max_voltage_limit=300,
              torque_nm=1.7, current_a=0.6, gear_ratio=257.0,
              assumed={"acceleration_limit_max": "range not read: the PM42-010-S260-R's",
                       "position_limit": "range not read: half of 526,375, as the PM42's"}),
    # --- DYNAMIXEL-P (PRO+): the PRO(A) table plus Protocol Type (13); figures of the pages
    # at ROBOTIS-GIT/emanual 0ef495a (PH54-200: its later page, 01ba971, with published gains)
    _pro_plus("PH54-200-S500-R", 2020, Firmware.P, page=_p_page("PH54-200-S500-R"),
              pulses_per_rev=1_003_846, position_limit=501_923, max_position=501_433,
              current_limit=22_740, velocity_limit=2_900, acceleration_limit=3_992_644,
              acceleration_limit_max=3_992_644, shutdown=52,
              torque_nm=44.7, current_a=9.3, gear_ratio=501.923),
    _pro_plus("PH54-100-S500-R", 2010, Firmware.P, page=_p_page("PH54-100-S500-R"),
              pulses_per_rev=1_003_846, position_limit=501_923, max_position=501_433,
              current_limit=15_900, velocity_limit=2_920, acceleration_limit=10_639,
              acceleration_limit_max=4_255_632,
              torque_nm=25.3, current_a=5.5, gear_ratio=501.923),
    _pro_plus("PH42-020-S300-R", 2000, Firmware.P, page=_p_page("PH42-020-S300-R"),
              pulses_per_rev=607_500, position_limit=303_750, max_position=303_454,
              current_limit=4_500, velocity_limit=2_920, acceleration_limit=10_765,
              acceleration_limit_max=4_306_173,
              torque_nm=5.1, current_a=1.5, gear_ratio=303.75),
    _pro_plus("PM54-060-S250-R", 2120, Firmware.P, page=_p_page("PM54-060-S250-R"),
              pulses_per_rev=502_834, position_limit=251_417, max_position=251_173,
              current_limit=7_980, velocity_limit=2_830, acceleration_limit=11_145,
              acceleration_limit_max=4_457_932,
              torque_nm=10.1, current_a=3.0, gear_ratio=251.417),
    _pro_plus("PM54-040-S250-R", 2110, Firmware.P, page=_p_page("PM54-040-S250-R"),
              pulses_per_rev=502_834, position_limit=251_417, max_position=251_173,
              current_limit=4_470, velocity_limit=2_840, acceleration_limit=11_037,
              acceleration_limit_max=4_414_976,
              torque_nm=3.9, current_a=1.9, gear_ratio=251.417),
    # its page prints the Acceleration Limit initial as "1,0867": 10,867 read
    _pro_plus("PM42-010-S260-R", 2100, Firmware.P, page=_p_page("PM42-010-S260-R"),
              pulses_per_rev=526_374, position_limit=263_187, max_position=262_931,
              current_limit=1_461, velocity_limit=2_600, acceleration_limit=10_867,
              acceleration_limit_max=4_346_756,
              torque_nm=1.7, current_a=0.6, gear_ratio=257.019),
)
# fmt: on

BY_NAME: Mapping[str, ModelFigures] = MappingProxyType({m.name: m for m in FAMILY})
BY_NUMBER: Mapping[int, ModelFigures] = MappingProxyType({m.number: m for m in FAMILY})

# Models of the family the emulator does not serve, and why (model number -> (name, reason)).
REFUSED: Mapping[int, tuple[str, str]] = MappingProxyType(
    {
        35072: (
            "L42-10-S300-R",
            "its table is not the PRO layout (e-Manual l42-10-s300-r: Position PID gains at "
            "590..594 and no velocity PI, Goal Position 0 ~ 4,095 at 4,096 pulse/rev, Goal "
            "Torque in 0.1 % of the maximum rather than a current)",
        ),
    }
)

DEFAULT_MODEL = "H54-200-S500-R"


def figures_of(model: str | int) -> ModelFigures:
    """A model's figures by e-Manual name or model number; ValueError naming the served ones
    (or why a known model is refused)."""
    found = BY_NAME.get(model) if isinstance(model, str) else BY_NUMBER.get(model)
    if found is not None:
        return found
    for number, (name, reason) in REFUSED.items():
        if model in (name, number):
            raise ValueError(f"the emulator does not serve the {name} (model {number}): {reason}")
    raise ValueError(f"no DYNAMIXEL PRO model {model!r}; the emulator serves: {', '.join(BY_NAME)}")
