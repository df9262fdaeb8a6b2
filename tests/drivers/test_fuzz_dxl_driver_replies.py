"""Property-based fuzzing of the driver's Protocol 2.0 receive path (hypothesis).

The driver (drivers/dynamixel: chain, device_io, scan) runs unmodified on dynamixel-sdk's
receive code; only the port is replaced by `FakeWirePort`, a `LowLatencyPortHandler` whose wire
is in-process: the emulator's pure `DynamixelChain` answers each instruction, and a hypothesis
strategy then mangles the replies (garbage before, between and after them, flipped, inserted or
deleted bytes, truncation, replies from strangers, duplicates) and delivers them in chunks at
arbitrary virtual times. The port's clock is virtual (it advances with every read), so the
SDK's busy-wait costs no real time and timeouts are exact.

Properties: nothing but `BusError` ever leaves the driver; a tick never outlasts its timeout
(or the last byte the line delivered, whichever is later); a value the driver calls valid is
exactly the device's; a clean tick after any mangled one is complete again; `disable()` that
returns means torque is off in every device, `enable()` that returns means it is on.

Case counts: `max_examples` below, times FUZZ_SCALE (environment, default 1). The long run:
    FUZZ_SCALE=50 .venv/bin/pytest -q --timeout=0 tests/drivers/test_fuzz_dxl_driver_replies.py
"""

from __future__ import annotations

import importlib
from collections.abc import Callable

import numpy as np
import pytest
from dynamixel_sdk import COMM_RX_CORRUPT, COMM_SUCCESS
from hypothesis import event, given
from hypothesis import strategies as st

import drivers.dynamixel.chain as chain_module
from drivers.dynamixel import (
    DynamixelChain,
    DynamixelChainConfig,
    DynamixelJointConfig,
    scan,
)
from drivers.dynamixel.port import LowLatencyPortHandler
from drivers.joint_bus import BusError
from sim_backend.dynamixel.chain import DynamixelChain as EmulatedChain
from sim_backend.dynamixel.device import H54Device
from sim_backend.dynamixel.protocol import PacketParser, build_status_packet
from tests.support.fuzzing import examples

# `drivers.dynamixel.scan` is also the name of the function the package exports.
scan_module = importlib.import_module("drivers.dynamixel.scan")
IDS = (1, 2, 3)
BAUD = 4_000_000
READ_STEP_MS = 0.01  # virtual time one readPort call takes when bytes are waiting
IDLE_STEP_MS = 0.1  # ... and when none are (the SDK polls an empty port)

pytestmark = pytest.mark.timeout(180)


Mangle = Callable[[bytes], list[tuple[float, bytes]]]  # replies -> [(delay ms, chunk)]


class FakeWirePort(LowLatencyPortHandler):
    """The SDK's port with an in-process wire and a virtual clock (see the module docstring)."""

    def __init__(self, devices: EmulatedChain, *, latency_timer_ms: float, margin_ms: float):
        super().__init__(
            "fake-wire", latency_timer_ms=latency_timer_ms, timeout_margin_ms=margin_ms
        )
        self.devices = devices
        self.is_open = True
        self.baudrate = BAUD
        self.tx_time_per_byte = (1000.0 / BAUD) * 10.0
        self.now_ms = 0.0
        self.mangle: Mangle | None = None
        self.mangle_instruction: Callable[[bytes], bytes] | None = None
        self._parser = PacketParser()
        self._pending: list[tuple[float, bytes]] = []
        self._rx = bytearray()
        self.last_byte_ms = 0.0
        self.idle_step_ms = IDLE_STEP_MS

    def getCurrentTime(self) -> float:
        return self.now_ms

    def _arrive(self) -> None:
        due = [chunk for at_ms, chunk in self._pending if at_ms <= self.now_ms]
        self._pending = [(at_ms, chunk) for at_ms, chunk in self._pending if at_ms > self.now_ms]
        for chunk in due:
            self._rx += chunk

    def clearPort(self) -> None:
        self._arrive()
        self._rx.clear()

    def writePort(self, packet) -> int:
        data = bytes(packet)
        heard = data if self.mangle_instruction is None else self.mangle_instruction(data)
        now_s = self.now_ms / 1000.0
        for instruction in self._parser.on_idle(now_s) + self._parser.feed(heard, now_s):
            replies = b"".join(r for _, r in self.devices.handle(instruction, self.now_ms / 1e3))
            chunks = [(0.0, replies)] if self.mangle is None else self.mangle(replies)
            for delay_ms, chunk in chunks:
                if chunk:
                    self._pending.append((self.now_ms + delay_ms, chunk))
                    self.last_byte_ms = max(self.last_byte_ms, self.now_ms + delay_ms)
        return len(data)

    def readPort(self, length: int) -> bytes:
        self._arrive()
        self.now_ms += READ_STEP_MS if self._rx else self.idle_step_ms
        count = max(0, min(length, len(self._rx)))
        data = bytes(self._rx[:count])
        del self._rx[:count]
        return data

    def getBytesAvailable(self) -> int:
        self._arrive()
        return len(self._rx)

    def closePort(self) -> None:
        self.is_open = False

    def quiet(self) -> None:
        """Let the line go idle long enough that every late byte has come and been flushed."""
        self.now_ms += 1000.0
        self._parser.on_idle(self.now_ms / 1000.0)  # a partial instruction times out
        self.clearPort()


# --- strategies ------------------------------------------------------------------------------

junk_bytes = st.lists(
    st.one_of(st.sampled_from([0xFF, 0xFD, 0x00, 0x55, 0x01, 0x02, 0x03]), st.integers(0, 255)),
    max_size=80,
).map(bytes)


# Parameter lengths a real answer to the driver can have: WRITE 0, 1-byte READ 1, PING 3,
# 4-byte READ 4, the state block 15. A CRC-good status with one of our IDs, no error number and
# one of these lengths IS, on the wire, that device's answer: nothing could tell a forged one
# from it, so the fuzz never forges one.
ANSWER_LENGTHS = (0, 1, 3, 4, 15)


@st.composite
def stranger_status(draw: st.DrawFn) -> bytes:
    """A CRC-good status packet that is not the expected one: another ID, an error number, or
    a length no answer has (see ANSWER_LENGTHS)."""
    dxl_id = draw(st.sampled_from([*IDS, 9, 200]))
    if dxl_id not in IDS:
        error = draw(st.sampled_from([0, 0x80, 1, 4, 7, 0x86]))
        return build_status_packet(dxl_id, error, draw(st.binary(max_size=20)))
    if draw(st.booleans()):  # an error reply: the driver reports it
        error = draw(st.sampled_from([1, 4, 7, 0x86]))
        return build_status_packet(dxl_id, error, draw(st.binary(max_size=20)))
    length = draw(st.integers(0, 20).filter(lambda n: n not in ANSWER_LENGTHS))
    return build_status_packet(
        dxl_id, draw(st.sampled_from([0, 0x80])), draw(st.binary(min_size=length, max_size=length))
    )


@st.composite
def mangled(draw: st.DrawFn, replies: bytes) -> list[tuple[float, bytes]]:
    """The replies as a hostile line might deliver them."""
    data = bytearray(replies)
    for _ in range(draw(st.integers(0, 3))):
        if not data:
            break
        how = draw(st.sampled_from(["flip", "insert", "delete", "truncate", "none"]))
        index = draw(st.integers(0, len(data) - 1))
        if how == "flip":
            data[index] ^= draw(st.integers(1, 255))
        elif how == "insert":
            data[index:index] = draw(st.one_of(junk_bytes, stranger_status()))
        elif how == "delete":
            del data[index : index + draw(st.integers(1, 4))]
        elif how == "truncate":
            del data[index:]
    data = draw(junk_bytes) + bytes(data) + draw(junk_bytes)
    if draw(st.booleans()):
        data += draw(stranger_status())
    cuts = sorted(draw(st.sets(st.integers(1, max(1, len(data) - 1)), max_size=6)))
    bounds = [0, *[c for c in cuts if c < len(data)], len(data)]
    chunks = [bytes(data[a:b]) for a, b in zip(bounds, bounds[1:], strict=False) if b > a]
    delays = draw(
        st.lists(st.floats(0.0, 8.0), min_size=len(chunks), max_size=len(chunks)).map(sorted)
    )
    return list(zip(delays, chunks, strict=True))


@st.composite
def heard(draw: st.DrawFn, instruction: bytes) -> bytes:
    """What the devices hear of an instruction: all of it, a corrupted copy, or nothing."""
    how = draw(st.sampled_from(["intact", "intact", "flip", "lost"]))
    if how == "intact":
        return instruction
    if how == "lost":
        return b""
    data = bytearray(instruction)
    data[draw(st.integers(0, len(data) - 1))] ^= draw(st.integers(1, 255))
    return bytes(data)


@st.composite
def any_replies(draw: st.DrawFn, replies: bytes) -> list[tuple[float, bytes]]:
    """Mangled replies, or arbitrary bytes instead of them."""
    if draw(st.integers(0, 3)) == 0:
        return [(draw(st.floats(0.0, 8.0)), draw(st.binary(max_size=200)))]
    return draw(mangled(replies))


# --- a chain on the fake wire ----------------------------------------------------------------


class Rig:
    """A `DynamixelChain` opened on a `FakeWirePort` whose devices are the emulator's."""

    def __init__(self) -> None:
        self.devices = EmulatedChain([H54Device(dxl_id, baud_index=6) for dxl_id in IDS])
        self.port: FakeWirePort | None = None
        self.mangle_next_port: Mangle | None = None  # for a port that scan() opens itself
        self.idle_step_ms = IDLE_STEP_MS
        joints = tuple(
            DynamixelJointConfig(
                dxl_id=dxl_id,
                direction=-1 if dxl_id == 2 else 1,
                offset_rad=0.1 * dxl_id,
                min_position_rad=-1.0,
                max_position_rad=1.0,
            )
            for dxl_id in IDS
        )
        self.chain = DynamixelChain(
            DynamixelChainConfig(port="fake-wire", baudrate=BAUD, joints=joints)
        )
        rng = np.random.default_rng(1)
        for device in self.devices.devices:  # distinct, non-trivial values in every field
            device.set_item("Present Position", int(rng.integers(-20_000, 20_000)))
            device.set_item("Present Velocity", int(rng.integers(-5000, 5000)))
            device.set_item("Present Current", int(rng.integers(-600, 600)))
            device.set_item("Present Temperature", int(rng.integers(20, 60)))

    def open_port(self, port: str, baudrate: int, **kwargs: float) -> FakeWirePort:
        """Stands in for `drivers.dynamixel.port.open_port`."""
        self.port = FakeWirePort(
            self.devices,
            latency_timer_ms=kwargs.get("latency_timer_ms", 1.0),
            margin_ms=kwargs.get("timeout_margin_ms", 2.0),
        )
        self.port.mangle = self.mangle_next_port
        self.port.idle_step_ms = self.idle_step_ms
        return self.port

    @property
    def wire(self) -> FakeWirePort:
        assert self.port is not None
        return self.port


@pytest.fixture
def new_rig(monkeypatch: pytest.MonkeyPatch) -> Callable[[], Rig]:
    """Makes a fresh, opened rig (one per hypothesis example: no state leaks between them)."""
    current: list[Rig] = []

    def open_port(port: str, baudrate: int, **kwargs: float) -> FakeWirePort:
        return current[-1].open_port(port, baudrate, **kwargs)

    monkeypatch.setattr(chain_module, "open_port", open_port)
    monkeypatch.setattr(scan_module, "open_port", open_port)

    def make() -> Rig:
        current.append(Rig())
        current[-1].chain.open()
        return current[-1]

    return make


def same_where_valid(state, reference) -> None:
    for name in ("position_rad", "velocity_rad_s", "current_a", "temperature_c"):
        got, want = getattr(state, name), getattr(reference, name)
        assert np.array_equal(got[state.valid], want[state.valid]), name
        assert np.isnan(got[~state.valid]).all(), name
    assert np.array_equal(state.hardware_error[state.valid], reference.hardware_error[state.valid])


def test_read_state_survives_any_reply_bytes(new_rig: Callable[[], Rig]) -> None:
    @examples(40)
    @given(data=st.data())
    def check(data: st.DataObject) -> None:
        rig = new_rig()
        wire = rig.wire
        reference = rig.chain.read_state()
        assert reference.valid.all()
        timeout_ms = wire.packet_timeout_ms((11 + rig.chain.layout.size) * len(IDS))
        wire.mangle = lambda replies: data.draw(any_replies(replies))
        started_ms = wire.now_ms
        state = rig.chain.read_state()  # must not raise
        elapsed_ms = wire.now_ms - started_ms
        wire.mangle = None
        last_byte_ms = wire.last_byte_ms - started_ms
        # each byte delivered costs one read at most, plus one idle poll
        budget_ms = max(timeout_ms, last_byte_ms) + 400 * READ_STEP_MS + 2 * IDLE_STEP_MS
        assert elapsed_ms <= budget_ms, (elapsed_ms, timeout_ms, last_byte_ms)
        same_where_valid(state, reference)
        assert len(state.errors) >= int((~state.valid).sum()), state.errors
        wire.quiet()
        clean = rig.chain.read_state()
        assert clean.valid.all(), clean.errors
        same_where_valid(clean, reference)

    check()


def test_single_reads_return_the_value_or_a_bus_error(new_rig: Callable[[], Rig]) -> None:
    @examples(80)
    @given(data=st.data(), dxl_id=st.sampled_from(IDS))
    def check(data: st.DataObject, dxl_id: int) -> None:
        rig = new_rig()
        io = rig.chain._io  # the checked single-device transactions (identification, enable)
        assert io is not None
        item = rig.chain.spec.item("Present Position")
        truth = rig.devices.device(dxl_id).item("Present Position")
        rig.wire.mangle = lambda replies: data.draw(any_replies(replies))
        started_ms = rig.wire.now_ms
        try:
            value = io.read_item(dxl_id, item)
        except BusError:
            pass
        else:
            assert value == truth
        finally:
            rig.wire.mangle = None
        timeout_ms = rig.wire.packet_timeout_ms(item.size + 11)
        last_byte_ms = rig.wire.last_byte_ms - started_ms
        elapsed_ms = rig.wire.now_ms - started_ms
        assert elapsed_ms <= max(timeout_ms, last_byte_ms) + 400 * READ_STEP_MS + 2 * IDLE_STEP_MS
        rig.wire.quiet()
        assert io.read_item(dxl_id, item) == truth  # and the next one is clean

    check()


def test_enable_and_disable_tell_the_truth_under_any_reply_bytes(
    new_rig: Callable[[], Rig],
) -> None:
    @examples(80)
    @given(data=st.data(), enable=st.booleans(), torque_before=st.booleans())
    def check(data: st.DataObject, enable: bool, torque_before: bool) -> None:
        rig = new_rig()
        if torque_before:
            rig.chain.enable()
        rig.wire.mangle = lambda replies: data.draw(any_replies(replies))
        rig.wire.mangle_instruction = lambda instruction: data.draw(heard(instruction))
        try:
            rig.chain.enable() if enable else rig.chain.disable()
        except BusError:
            pass  # what went wrong is reported; nothing is claimed
        else:
            torque = [device.torque_enabled for device in rig.devices.devices]
            assert torque == [enable] * len(IDS)
        finally:
            rig.wire.mangle = None
            rig.wire.mangle_instruction = None
            rig.wire.quiet()
        rig.chain.disable()  # a clean line: it works again
        assert not any(device.torque_enabled for device in rig.devices.devices)

    check()


def test_scan_returns_only_what_answered_or_a_bus_error(new_rig: Callable[[], Rig]) -> None:
    @examples(10)
    @given(data=st.data(), ids=st.sampled_from([None, (1, 2, 3, 4)]), silent=st.booleans())
    def check(data: st.DataObject, ids: tuple[int, ...] | None, silent: bool) -> None:
        rig = new_rig()
        rig.chain.close()
        rig.idle_step_ms = 1.0  # a scan waits ~1 s of virtual time: poll it coarsely
        # A silent line makes the broadcast find nothing, so the per-ID fallback runs too.
        rig.devices.faults.silent_ids = set(IDS) if silent else set()
        rig.mangle_next_port = lambda replies: data.draw(any_replies(replies))
        try:
            found = scan("fake-wire", BAUD, ids)
        except BusError:
            event("scan: BusError")
            return
        finally:
            rig.mangle_next_port = None
        event(f"scan: {len(found)} found")
        wanted = range(253) if ids is None else ids
        assert all(device.dxl_id in wanted for device in found)
        assert [d.dxl_id for d in found] == sorted({d.dxl_id for d in found})

    check()


def test_a_short_reply_is_not_read_as_data(new_rig: Callable[[], Rig]) -> None:
    """What the fuzzing found: a CRC-good status with 2 data bytes answering a 4-byte READ was
    returned as a value whose upper half was the packet's CRC (the SDK's readRx does not check
    LEN). Also a PING reply without its 3 parameters."""
    rig = new_rig()
    io = rig.chain._io
    assert io is not None
    short = build_status_packet(1, 0, b"\x00\x00")
    rig.wire.mangle = lambda replies: [(0.0, short)]
    with pytest.raises(BusError, match="answered with 2 data bytes, expected 4"):
        io.read_item(1, rig.chain.spec.item("Present Position"))
    rig.wire.quiet()
    rig.wire.mangle = lambda replies: [(0.0, build_status_packet(1, 0, b""))]
    assert io.ping(1) == (0, COMM_RX_CORRUPT)
    rig.wire.mangle = None
    rig.wire.quiet()
    assert io.ping(1) == (54024, COMM_SUCCESS)


def test_a_sync_read_reply_of_the_wrong_length_is_not_decoded(
    new_rig: Callable[[], Rig],
) -> None:
    """A CRC-good status from ID 1 with 5 bytes, ahead of the real replies: skipped (the state
    block has 15), and ID 1's real reply still counts."""
    rig = new_rig()
    reference = rig.chain.read_state()
    stranger = build_status_packet(1, 0, b"\x01\x02\x03\x04\x05")
    rig.wire.mangle = lambda replies: [(0.0, stranger + replies)]
    state = rig.chain.read_state()
    assert state.valid.all(), state.errors
    same_where_valid(state, reference)
