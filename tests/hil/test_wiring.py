"""From the configuration to the drivers: the mounting reaches them, the tick's wire budget by hand
(drivers/tick_budget.py)."""

from __future__ import annotations

import pytest

from drivers.tick_budget import can_frame_bits, tick_budget
from hil.config import load_config
from hil.wiring import Connection
from hil.wiring.hardware import bus_config


def test_can_frame_bits_by_the_standard() -> None:
    # ISO 11898-1 classic frame: 44 + 8n bits + 3 IFS; the worst case stuffs (34 + 8n - 1) / 4
    # more: the textbook 135 bits for 8 bytes (Davis et al., Real-Time Systems 35, 2007)
    assert can_frame_bits(0, worst_case_stuffing=False) == 47
    assert can_frame_bits(8, worst_case_stuffing=False) == 111
    assert can_frame_bits(8) == 135
    assert can_frame_bits(0) == 55
    with pytest.raises(ValueError, match="0..8"):
        can_frame_bits(9)


def test_dyros_jet_tick_budget_by_hand() -> None:
    config = load_config(robot="dyros-jet")
    budget = tick_budget(bus_config(config, Connection.from_config(config)), config.loop.period_s)
    # CAN at 1 Mbit/s: SYNC 55 bits, 12 encoder TPDOs of 4 bytes (47 + 32 + 16 = 95 bits),
    # 2 x 2 force/torque TPDOs of 6 bytes (47 + 48 + 20 = 115 bits)
    assert budget.can_s == pytest.approx((55 + 12 * 95 + 4 * 115) / 1e6)
    # RS-485 at 3 Mbit/s: sync read 14 + 12 bytes, 12 replies of 11 + 15 bytes; write 14 + 12 x 5
    assert budget.sync_read_s == pytest.approx((26 + 12 * 26) * 10 / 3e6)
    assert budget.sync_write_s == pytest.approx(74 * 10 / 3e6)
    assert budget.usb_latency_s == pytest.approx(1e-3)
    assert budget.sequential_s == pytest.approx(1.655e-3 + 1.1267e-3 + 1e-3 + 0.2467e-3, rel=1e-3)
    assert budget.overlapped_s == pytest.approx(1.1267e-3 + 1e-3 + 0.2467e-3, rel=1e-3)
    assert budget.overlapped_s < budget.sequential_s < budget.period_s


def test_the_configurations_mounting_reaches_the_drivers() -> None:
    # a direction hard-wired to +1 between the file and the drivers would pass every run with
    # the built-in testbed (direction +1, offset 0): set the file's values and read them back
    config = load_config()
    joint = config.joints[0].model_copy(
        update={
            "encoder_direction": -1,
            "encoder_offset_rad": 0.3,
            "motor_direction": -1,
            "motor_offset_rad": 0.2,
        }
    )
    config = config.replaced(joints=[joint])
    bus = bus_config(config, Connection.from_config(config))
    (encoder,) = bus.can_channels[0].encoders
    (actuator,) = bus.chains[0].joints
    assert (encoder.direction, encoder.offset_rad) == (-1, 0.3)
    assert (actuator.direction, actuator.offset_rad) == (-1, 0.2)
