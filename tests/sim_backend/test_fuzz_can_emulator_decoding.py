"""Property-based fuzzing of the emulator's CAN receive path (hypothesis).

- The SLCAN adapter on a pty (`SlcanPty`): arbitrary bytes from the host, split at arbitrary
  points. It never raises, answers only with the protocol's replies, passes to the bus only
  frames that a well-formed frame command in the input spelled out, and after any garbage a
  line end plus a clean command sequence works exactly.
- An emulated CANopen node (`LinkEncoderNode`: NMT, SDO server, SYNC -> TPDO): arbitrary
  frames. It never raises, sends only its own COB-IDs with at most 8 bytes, and its read-only
  objects (device type, identity, resolution) keep their values.

Case counts: `max_examples` below, times FUZZ_SCALE (environment, default 1). The long run:
    FUZZ_SCALE=50 .venv/bin/pytest -q --timeout=0 \
        tests/sim_backend/test_fuzz_can_emulator_decoding.py
"""

from __future__ import annotations

import os
import select
import time

import can
import pytest
from hypothesis import given
from hypothesis import strategies as st

from sim_backend.canbus.encoder_node import LinkEncoderNode
from sim_backend.canbus.slcan_pty import SlcanPty
from tests.support.fuzzing import examples

NODE = 5
N = 983_040

pytestmark = pytest.mark.timeout(120)


# --- the SLCAN adapter -----------------------------------------------------------------------

# Characters of the SLCAN command set, so that near-valid commands are frequent.
slcan_chars = st.lists(
    st.one_of(
        st.sampled_from(list(b"tTrRSsOLCVvNFZMm0123456789ABCDEFabcdef\r\a\n")),
        st.integers(0, 255),
    ),
    max_size=30,
).map(bytes)
hex_digits = st.text(alphabet="0123456789ABCDEFabcdef", max_size=20)


@st.composite
def near_frame_command(draw: st.DrawFn) -> bytes:
    """A frame command whose parts may be off: id width, DLC, payload length, kind."""
    kind = draw(st.sampled_from("tTrRdD"))
    id_digits = draw(st.sampled_from([3, 8, 2, 4, 9]))
    identifier = draw(
        st.text(alphabet="0123456789ABCDEFabcdef", min_size=id_digits, max_size=id_digits)
    )
    dlc = draw(st.sampled_from("0123456789F"))
    return (kind + identifier + dlc + draw(hex_digits)).encode()


slcan_command = st.one_of(
    near_frame_command(),
    st.sampled_from(
        [
            b"O",
            b"L",
            b"C",
            b"S8",
            b"S4",
            b"S9",
            b"s0014",
            b"V",
            b"v",
            b"N",
            b"F",
            b"Z0",
            b"Z1",
            b"M00000000",
            b"mFFFFFFFF",
            b"",
            b"X",
        ]
    ),
    slcan_chars,
)
slcan_text = st.lists(
    st.tuples(slcan_command, st.sampled_from([b"\r", b"\r", b"\a", b""])), max_size=12
).map(lambda parts: b"".join(command + end for command, end in parts))

REPLY_TOKENS = (b"\r", b"\a", b"z\r", b"Z\r", b"V1013\r", b"v1013\r", b"NFJH1\r")


def only_protocol_replies(data: bytes) -> bool:
    """True if `data` is a sequence of the adapter's replies (OK, BEL, z, Z, version, F..)."""
    index = 0
    while index < len(data):
        for token in REPLY_TOKENS:
            if data.startswith(token, index):
                index += len(token)
                break
        else:
            flags = data[index : index + 4]
            if len(flags) == 4 and flags[:1] == b"F" and flags[3:] == b"\r":
                int(flags[1:3], 16)
                index += 4
            else:
                return False
    return True


def spelled_out(frame: can.Message, text: bytes) -> bool:
    """True if a line of `text` is exactly the SLCAN command for `frame` (any hex case)."""
    if frame.is_extended_id:
        head = f"{'R' if frame.is_remote_frame else 'T'}{frame.arbitration_id:08X}{frame.dlc}"
    else:
        head = f"{'r' if frame.is_remote_frame else 't'}{frame.arbitration_id:03X}{frame.dlc}"
    payload = "" if frame.is_remote_frame else bytes(frame.data).hex().upper()
    wanted = (head + payload).upper().encode()
    lines = text.replace(b"\a", b"\r").split(b"\r")
    return any(line.lstrip(b"\n").upper() == wanted for line in lines)


def read_host(fd: int) -> bytes:
    data = b""
    while select.select([fd], [], [], 0.0)[0]:
        chunk = os.read(fd, 4096)
        if not chunk:
            break
        data += chunk
    return data


def exchange(adapter: SlcanPty, host: int, chunk: bytes) -> tuple[list[can.Message], bytes]:
    os.write(host, chunk)
    frames: list[can.Message] = []
    deadline = time.monotonic() + 2.0
    while time.monotonic() < deadline:  # until the adapter has taken every byte
        if not select.select([adapter.fileno()], [], [], 0.0)[0]:
            break
        frames += adapter.read_frames()
    return frames, read_host(host)


def test_slcan_adapter_survives_any_host_bytes() -> None:
    adapter = SlcanPty(bus_bitrate=1_000_000)
    host = os.open(adapter.port_path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    try:

        @examples(80)
        @given(text=slcan_text, cuts=st.lists(st.integers(0, 200), max_size=6))
        def check(text: bytes, cuts: list[int]) -> None:
            bounds = sorted({0, len(text), *[c for c in cuts if c < len(text)]})
            frames: list[can.Message] = []
            replies = b""
            for start, end in zip(bounds, bounds[1:], strict=False):
                got, answer = exchange(adapter, host, text[start:end])
                frames += got
                replies += answer
            assert only_protocol_replies(replies), replies
            for frame in frames:
                assert frame.dlc <= 8 and len(frame.data) == (
                    0 if frame.is_remote_frame else frame.dlc
                )
                assert spelled_out(frame, text), (frame, text)
            # A line end ends whatever the garbage left half-written; then a clean session.
            exchange(adapter, host, b"\r")
            frames, answer = exchange(adapter, host, b"C\rS8\rO\rt1232AABB\rF\r")
            assert answer == b"\r\r\rz\rF00\r", answer
            assert [(f.arbitration_id, bytes(f.data)) for f in frames] == [(0x123, b"\xaa\xbb")]
            assert adapter.on_bus

        check()
    finally:
        os.close(host)
        adapter.close()


# --- an emulated CANopen node ----------------------------------------------------------------

node_cob_ids = st.sampled_from(
    [0x000, 0x080, 0x600 + NODE, 0x580 + NODE, 0x700 + NODE, 0x180 + NODE, 0x600 + 6, 0x7FF]
)


@st.composite
def any_frame(draw: st.DrawFn) -> can.Message:
    extended = draw(st.integers(0, 9)) == 0
    remote = draw(st.integers(0, 9)) == 0
    cob_id = draw(
        st.integers(0, 0x1FFF_FFFF) if extended else st.one_of(node_cob_ids, st.integers(0, 0x7FF))
    )
    if cob_id == 0x000 and not extended:  # NMT: command and target from the valid sets often
        data = bytes(
            (
                draw(
                    st.one_of(st.sampled_from([0x01, 0x02, 0x80, 0x81, 0x82]), st.integers(0, 255))
                ),
                draw(st.sampled_from([0, NODE, 6])),
            )
        ) + draw(st.binary(max_size=6))
    else:
        data = draw(st.binary(max_size=8))
    return can.Message(
        arbitration_id=cob_id,
        is_extended_id=extended,
        is_remote_frame=remote,
        dlc=len(data),
        data=None if remote else data,
    )


def sdo_upload(node: LinkEncoderNode, index: int, subindex: int, now_s: float) -> int:
    request = can.Message(
        arbitration_id=0x600 + NODE,
        is_extended_id=False,
        data=bytes((0x40, index & 0xFF, index >> 8, subindex, 0, 0, 0, 0)),
    )
    responses = [m for m in node.handle(request, now_s) if m.arbitration_id == 0x580 + NODE]
    assert len(responses) == 1, responses
    data = bytes(responses[0].data)
    assert data[0] & 0xE3 == 0x43, data.hex()  # expedited upload with size
    size = 4 - ((data[0] >> 2) & 0x3)
    return int.from_bytes(data[4 : 4 + size], "little")


@examples(100)
@given(frames=st.lists(any_frame(), max_size=40))
def test_encoder_node_survives_any_frames(frames: list[can.Message]) -> None:
    node = LinkEncoderNode(NODE, lambda: 0.25)
    own = {0x180 + NODE, 0x580 + NODE, 0x700 + NODE, 0x80 + NODE}
    now_s = 0.0
    sent: list[can.Message] = node.poll(now_s)
    for frame in frames:
        now_s += 0.001
        sent += node.handle(frame, now_s)
        sent += node.poll(now_s)
    for message in sent:
        assert not message.is_extended_id and len(message.data) <= 8
        # a TPDO COB-ID may be re-pointed by a valid SDO write; the rest are fixed
        assert message.arbitration_id in own or message.arbitration_id < 0x580, message
    # Whatever happened, the read-only objects kept their values: bring the node to
    # Pre-operational (SDO works there; a boot in progress is over a second later) and read.
    now_s += 1.0
    node.poll(now_s)
    pre_operational = can.Message(arbitration_id=0, is_extended_id=False, data=bytes((0x80, 0)))
    node.handle(pre_operational, now_s)
    assert sdo_upload(node, 0x1000, 0, now_s) == 0x0002_0196
    assert sdo_upload(node, 0x6001, 0, now_s) == N
    assert sdo_upload(node, 0x1018, 4, now_s) == 0x4060_0000 + NODE
