"""The exit path on a dead Dynamixel port: `disable()` says the port is gone and that torque
could not be turned off, and never claims a command that did not reach the wire.

The port dies the way it does for a user: the emulator process (the other end of the pty)
stops while the chain is open with torque on; afterwards every read or write of the pty fails
with EIO. A fake serial object covers the case a pty cannot stage on demand: a port that fails
after the command was written, before its reply.
"""

from __future__ import annotations

import errno

import numpy as np
import pytest

from drivers.dynamixel import (
    DynamixelChain,
    DynamixelChainConfig,
    DynamixelJointConfig,
    PortGoneError,
)
from drivers.dynamixel.port import LowLatencyPortHandler
from drivers.joint_bus import BusError
from sim_backend.dynamixel.testing import spawn_emulated_chain
from tests.support.load_conditions import FUNCTIONAL_LATENCY_TIMER_MS

pytestmark = pytest.mark.timeout(60)

IDS = (1, 2)
# Generous reply timeout: the emulator is another process on a shared machine.
LATENCY_MS = FUNCTIONAL_LATENCY_TIMER_MS


def make_config(port: str) -> DynamixelChainConfig:
    joints = tuple(
        DynamixelJointConfig(dxl_id=i, min_position_rad=-1.0, max_position_rad=1.0) for i in IDS
    )
    return DynamixelChainConfig(
        port=port, baudrate=4_000_000, joints=joints, latency_timer_ms=LATENCY_MS
    )


def test_disable_on_a_pty_whose_other_end_closed_says_the_port_is_gone() -> None:
    with spawn_emulated_chain(ids=IDS) as emu:
        chain = DynamixelChain(make_config(emu.port_path))
        chain.open()
        chain.enable()
        assert chain.read_state().torque_enabled.all()
        emu.stop()  # the device vanishes: the other end of the pty is closed
        with pytest.raises(PortGoneError) as raised:
            chain.disable()
        message = str(raised.value)
        assert "Port is in use" not in message
        assert f"port {emu.port_path} is gone" in message and "Errno 5" in message
        assert "torque could not be turned off" in message
        assert "no Torque Enable = 0 reached ID 1" in message
        assert "nothing was sent to ID 2" in message
        assert "confirmed" not in message  # no success is claimed
        assert not raised.value.packet_was_sent
        assert chain.port_failure is not None and "Errno 5" in chain.port_failure
        # Every later call says the same, without touching the port again.
        with pytest.raises(PortGoneError, match="is gone"):
            chain.read_state()
        with pytest.raises(PortGoneError, match="is gone"):
            chain.write_goals(np.zeros(len(IDS)))
        with pytest.raises(PortGoneError, match="no Torque Enable = 0 reached ID 1"):
            chain.disable()
        chain.close()  # releasing a dead port is quiet


def test_a_port_that_dies_during_a_tick_is_reported_as_gone_not_as_busy() -> None:
    with spawn_emulated_chain(ids=IDS) as emu:
        chain = DynamixelChain(make_config(emu.port_path))
        chain.open()
        emu.stop()
        with pytest.raises(PortGoneError, match="is gone"):
            chain.read_state()  # was: termios.error escaping as a traceback
        with pytest.raises(PortGoneError) as raised:
            chain.disable()
        assert "Port is in use" not in str(raised.value)
        chain.close()


def test_an_interrupted_transaction_does_not_leave_the_port_busy() -> None:
    """Ctrl-C inside the SDK's busy-wait leaves its `is_using` flag set; the exit path's
    disable() must still reach the devices."""
    with (
        spawn_emulated_chain(ids=IDS) as emu,
        DynamixelChain(make_config(emu.port_path)) as chain,
    ):
        chain.enable()
        chain.port_handler.is_using = True  # what an interrupted transaction leaves
        chain.disable()
        assert [emu.item(i, "Torque Enable") for i in IDS] == [0, 0]


class _DyingSerial:
    """A pyserial stand-in: writes go through, the first read fails like a vanished adapter."""

    def __init__(self) -> None:
        self.written: list[bytes] = []
        self.in_waiting = 0

    def reset_input_buffer(self) -> None:
        pass

    def write(self, packet: list[int]) -> int:
        self.written.append(bytes(packet))
        return len(packet)

    def read(self, length: int) -> bytes:
        raise OSError(errno.EIO, "Input/output error")


def test_a_port_failing_after_the_command_was_written_says_the_state_is_unknown() -> None:
    with spawn_emulated_chain(ids=IDS) as emu:
        chain = DynamixelChain(make_config(emu.port_path))
        chain.open()
        port: LowLatencyPortHandler = chain.port_handler
        port.ser.close()
        port.ser = _DyingSerial()  # the port now fails between the write and the reply
        with pytest.raises(PortGoneError) as raised:
            chain.disable()
        message = str(raised.value)
        assert raised.value.packet_was_sent and len(port.ser.written) == 1
        assert "Torque Enable = 0 was sent to ID 1" in message
        assert "its torque state is unknown" in message
        assert "nothing was sent to ID 2" in message
        with pytest.raises(PortGoneError, match="no Torque Enable = 0 reached ID 1"):
            chain.disable()
        assert len(port.ser.written) == 1  # the dead port was not touched again
        port.is_open = False


def test_the_error_is_a_bus_error_the_loop_already_catches() -> None:
    assert issubclass(PortGoneError, BusError)
