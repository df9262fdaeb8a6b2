"""The CAN bring-up's SDO transfers wait for a node served by a process that works
(drivers/canbus/node_bringup.py `_sdo_transfer`, drivers/peer_wait.py): a loaded machine
delays a lock-step emulator's SDO answer past canopen's 0.3 s, which aborted a run at open
(MANIPULATOR-H's force sensor). On hardware (no patience) the timeout stays what it was."""

from __future__ import annotations

import time

import can
import pytest

from drivers.canbus import CanDeviceError, ForceSensorConfig
from drivers.peer_wait import PeerLook, PeerWait
from sim_backend.canbus import ForceSensorNode
from sim_backend.canbus.cia301 import SDO_REQUEST_COB_ID_BASE
from tests.support.can_rig import Rig

pytestmark = pytest.mark.timeout(30)

LATE_S = 0.45  # past canopen's 0.3 s SDO timeout


class _LateFirstAnswer(ForceSensorNode):
    """A force sensor whose server is busy for LATE_S on its first SDO request (the emulator's
    process kept from the CPU), then answers it."""

    late = True

    def handle(self, msg: can.Message, now_s: float) -> list[can.Message]:
        if self.late and msg.arbitration_id == SDO_REQUEST_COB_ID_BASE + 7:
            self.late = False
            time.sleep(LATE_S)
        return super().handle(msg, now_s)


class _Working:
    """A serving process that is always runnable (it is working on the answer)."""

    def look(self) -> PeerLook:
        return PeerLook(runnable=True, cpu_s=0.0, state="running")


def _rig(**kwargs) -> tuple[Rig, _LateFirstAnswer]:
    node = _LateFirstAnswer(7, lambda: 12.5)
    return Rig([node], [], force_sensor=ForceSensorConfig(7), **kwargs), node


def test_a_late_sdo_answer_from_a_working_emulator_is_waited_for() -> None:
    rig, node = _rig(patience=PeerWait(_Working()))
    try:
        rig.open()
        reading = rig.tick()
    finally:
        rig.close()
    assert not node.late  # the late answer happened
    assert reading.force.valid and reading.force.force_n == pytest.approx(12.5, abs=1e-3)


def test_without_patience_a_late_sdo_answer_fails_open_naming_the_node() -> None:
    rig, _ = _rig()
    try:
        with pytest.raises(CanDeviceError, match="no SDO answer reading device type 0x1000 within"):
            rig.open()
    finally:
        rig.close()
