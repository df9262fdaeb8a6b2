"""The emulator's H54-200-S500-R control table pins the servo gains where the e-Manual puts
them, with the manual's initial values.

Literals from the ROBOTIS e-Manual, H54-200-S500-R, "Control Table of RAM Area"
(https://emanual.robotis.com/docs/en/dxl/pro/h54-200-s500-r/): Velocity I Gain 586 (initial
14), Velocity P Gain 588 (initial 399), Position P Gain 594 (initial 32), 2 bytes each,
read/write, RAM, range 0..65535. The driver keeps its own table
(tests/drivers/test_h54_gain_addresses_driver.py): separate on purpose.
"""

from __future__ import annotations

import pytest

from sim_backend.dynamixel.control_table import H54_LAYOUT, Access, Area
from sim_backend.dynamixel.device import H54Device
from sim_backend.dynamixel.protocol import ErrorCode

E_MANUAL_GAINS = {  # name: (address, initial value)
    "Velocity I Gain": (586, 14),
    "Velocity P Gain": (588, 399),
    "Position P Gain": (594, 32),
}


@pytest.mark.parametrize(
    ("name", "address", "initial"), [(n, *v) for n, v in E_MANUAL_GAINS.items()]
)
def test_gain_item_matches_the_e_manual(name: str, address: int, initial: int) -> None:
    item = H54_LAYOUT[name]
    assert (item.address, item.size, item.default) == (address, 2, initial)
    assert (item.area, item.access) == (Area.RAM, Access.READ_WRITE)
    assert (item.minimum, item.maximum) == (0, 65_535)
    # and the device serves it there, on the wire's byte order
    device = H54Device(1)
    assert device.read(address, 2) == (ErrorCode.NONE, initial.to_bytes(2, "little"))
    assert device.write(address, (1234).to_bytes(2, "little")) == ErrorCode.NONE
    assert device.item(name) == 1234
