"""The bus against a lock-step emulator (`links_after_actuators`): the emulator sends a SYNC's
TPDOs before it answers the sync read, so once the actuators answered, every TPDO of that SYNC
is already in the port's buffer. Collecting the links after the actuators with a short wait
must then lose none that came (hundreds of ticks, every link valid), and a dead encoder is
missing at once instead of after a wait sized for a slow emulator."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from drivers.dynamixel_can_bus import DynamixelCanBus
from sim_backend.emulator_process import emulator_process
from sim_backend.scenario import FaultEvent, Scenario
from tests.drivers.test_joint_mounting_direction_offset import bus_for, emulator_spec_here

pytestmark = pytest.mark.timeout(90)

TICKS = 300
SHORT_WAIT_S = 0.001  # far below any emulator's stepping time: only the order makes it work


def _lockstep_bus(endpoints: dict) -> DynamixelCanBus:
    config = dataclasses.replace(
        bus_for(endpoints).config, links_after_actuators=True, link_timeout_s=SHORT_WAIT_S
    )
    return DynamixelCanBus(config)


def _link_valid(spec, ticks: int) -> np.ndarray:
    with emulator_process(spec) as emulator:
        bus = _lockstep_bus(emulator.endpoints)
        bus.open()
        try:
            return np.array([bool(bus.read().link_valid[0]) for _ in range(ticks)])
        finally:
            bus.close()


def test_collecting_the_links_after_the_actuators_loses_no_tpdo() -> None:
    assert _link_valid(emulator_spec_here(), TICKS).all()


def test_a_dead_encoder_is_missing_on_the_tick_it_stops() -> None:
    fault = FaultEvent("dead_encoder", start_s=0.5)  # from tick 100 on (the first SYNC is t = 0)
    spec = dataclasses.replace(emulator_spec_here(), scenario=Scenario(faults=(fault,)))
    valid = _link_valid(spec, 200)
    assert valid[:100].all()
    assert not valid[101:].any()
