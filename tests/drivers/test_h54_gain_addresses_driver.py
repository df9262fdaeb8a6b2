"""The driver's H54-200-S500-R control table pins the servo gains where the e-Manual puts them.

Literals from the ROBOTIS e-Manual, H54-200-S500-R, "Control Table of RAM Area"
(https://emanual.robotis.com/docs/en/dxl/pro/h54-200-s500-r/): Velocity I Gain 586, Velocity P
Gain 588, Position P Gain 594, 2 bytes each, read/write, RAM. The emulator keeps its own table
(tests/sim_backend/test_h54_gain_addresses_emulator.py): the two are separate on purpose, so
that each is checked against the manual, not against the other.
"""

from __future__ import annotations

import pytest

from drivers.dynamixel.control_table import H54_200_S500_R

E_MANUAL_GAINS = {
    "Velocity I Gain": 586,
    "Velocity P Gain": 588,
    "Position P Gain": 594,
}


@pytest.mark.parametrize(("name", "address"), E_MANUAL_GAINS.items())
def test_gain_item_matches_the_e_manual(name: str, address: int) -> None:
    item = H54_200_S500_R.item(name)
    assert (item.address, item.size, item.signed, item.writable) == (address, 2, False, True)
    assert not H54_200_S500_R.is_eeprom(item)  # RAM: back to default on reboot
