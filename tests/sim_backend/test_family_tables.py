"""The driver's and the emulator's tables of the DYNAMIXEL PRO family agree.

Both are written from the ROBOTIS e-Manual on their own (drivers/dynamixel/models.py and
control_table.py; sim_backend/dynamixel/models.py and control_table.py), on purpose: the two
sides of the wire must not share a table, or a typo in it would hold on both and no test would
see it. This test compares them figure by figure, so that a typo on either side shows.
"""

from __future__ import annotations

import dataclasses
import math

import pytest

from drivers.dynamixel import MODELS, REGISTERS, model_number
from drivers.dynamixel.models import ACTUATOR_MODELS, ASSUMED_CURRENT_CAPS
from drivers.dynamixel.models import REFUSED as DRIVER_REFUSED
from sim_backend.dynamixel import device_model
from sim_backend.dynamixel.control_table import Access, Area
from sim_backend.dynamixel.models import FAMILY, ModelFigures
from sim_backend.dynamixel.models import REFUSED as EMULATOR_REFUSED

NAMES = [m.name for m in FAMILY]


def test_both_sides_know_the_same_models_and_refuse_the_same() -> None:
    assert sorted((m.number, m.name) for m in FAMILY) == sorted(
        (m.number, m.name) for m in ACTUATOR_MODELS.values()
    )
    assert dict(DRIVER_REFUSED).keys() == dict(EMULATOR_REFUSED).keys()
    assert [v[0] for v in DRIVER_REFUSED.values()] == [v[0] for v in EMULATOR_REFUSED.values()]


@pytest.mark.parametrize("name", NAMES)
def test_the_driver_and_the_emulator_agree_on_a_model(name: str) -> None:
    driver = MODELS[model_number(name)]
    emulated = device_model(name)
    figures = emulated.figures
    layout = emulated.layout
    # every register the driver uses: same address, size, signedness, access and area
    for register in REGISTERS:
        mine = driver.item(register)
        theirs = layout[mine.name]  # the driver item carries the model's own name
        assert (mine.address, mine.size, mine.signed) == (
            theirs.address,
            theirs.size,
            theirs.signed,
        ), register
        assert mine.writable == (theirs.access is Access.READ_WRITE), register
        assert driver.is_eeprom(mine) == (theirs.area is Area.EEPROM), register
    # units
    assert driver.units.pulses_per_rev == figures.pulses_per_rev
    assert driver.units.position_limit_pulses == figures.position_limit
    assert driver.units.velocity_unit_rpm == figures.velocity_unit_rpm
    assert driver.units.current_unit_a == figures.current_unit_a
    assert math.isclose(
        driver.units.torque_constant_nm_per_a,
        figures.continuous_torque_nm / figures.continuous_current_a,
    )
    # caps and ranges
    assert driver.torque_limit_max_raw == layout[driver.item("Torque Limit").name].maximum
    gain = layout[driver.item("Position P Gain").name]
    assert driver.gain_max_raw == gain.maximum
    assert dict(driver.baud_rates_bps) == dict(emulated.baud_rates)
    assert driver.ram_start_address == layout["Torque Enable"].address
    # the indirect map
    indirect = emulated.indirect
    assert (driver.indirect_address_first, driver.indirect_data_first, driver.indirect_count) == (
        indirect.address_base,
        indirect.data_base,
        indirect.count,
    )
    assert driver.indirect_target_range == (indirect.target_min, indirect.target_max)
    # an assumed cap is assumed on both sides
    assert (name in ASSUMED_CURRENT_CAPS) == ("current_limit_max" in figures.assumed)


def test_every_assumption_names_a_figure_and_says_why() -> None:
    fields = {f.name for f in dataclasses.fields(ModelFigures)}
    for model in FAMILY:
        for figure, why in model.assumed.items():
            assert figure in fields, (model.name, figure)
            assert len(why) > 20, (model.name, figure)


def test_a_model_the_family_refuses_is_refused_with_its_reason_on_both_sides() -> None:
    with pytest.raises(ValueError, match="L42-10-S300-R.*not the PRO layout"):
        device_model("L42-10-S300-R")
    with pytest.raises(ValueError, match="L42-10-S300-R.*not the PRO layout"):
        MODELS.get(35072) or model_number("L42-10-S300-R")
    with pytest.raises(ValueError, match="serves: H54-200-S500-R"):
        device_model("XM430-W350")
