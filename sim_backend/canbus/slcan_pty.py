"""Emulated serial-line CAN adapter (Lawicel SLCAN ASCII protocol) on a pseudo-terminal.

Another process opens `port_path` exactly as it would open a USB-serial CAN adapter:

    can.Bus(interface="slcan", channel=port_path, bitrate=1_000_000, sleep_after_open=0)

and its frames reach the emulated CAN segment through this object. The emulator's event loop
owns the master side: it waits on `fileno()`, calls `read_frames()` for the host's frames and
`send_frame()` for the bus's frames. No thread, no blocking call.

Protocol (Lawicel CANUSB manual; python-can `can/interfaces/slcan.py` is the host side). Every
command ends with CR; the adapter answers CR for OK and BEL (0x07) for an error:

    Sn      bitrate, channel closed only: S0 10k, S1 20k, S2 50k, S3 100k, S4 125k, S5 250k,
            S6 500k, S7 750k, S8 1M, S9 83.3k (the table python-can and CANable use; the
            original Lawicel S7 is 800k)
    sxxyy   bitrate from SJA1000 BTR0/BTR1 at the 8 MHz CAN clock python-can assumes
    O / L   open the channel (L = listen only: the host may not transmit); needs a bitrate
    C       close the channel (always OK)
    tiiildd.. / Tiiiiiiiildd..   standard / extended data frame, host -> bus; answered "z" CR
    riiil / Riiiiiiiil           remote frames; answered "z" CR / "Z" CR like t / T
    V, v, N version and serial number ("V1013", "v1013", "NFJH1")
    F       status flags (channel open only), cleared when read: bit 3 data overrun,
            bit 5 error passive, bit 7 bus error
    Z0      timestamps off (OK); Z1 is refused: this adapter never appends timestamps
    Mxxxxxxxx, mxxxxxxxx   acceptance code / mask: accepted and ignored (all frames pass)
    an empty command (python-can sends one for "no data bitrate") is answered OK; CAN FD
    frames (d, D, b, B) and anything else get BEL.
Bus -> host frames are sent as "t..." / "T..." / "r..." / "R..." lines without timestamp.

Adapter state honoured: frames flow only while the channel is open. If the host's bitrate
differs from the segment's (`bus_bitrate`), the adapter cannot take part in the bus (a real
one would see only bit errors and get no acknowledge): the host sees no frames from the nodes,
its own frames never reach them, and flag bits 5 and 7 are set in the F status.

The pty is put in raw mode, the master is non-blocking, and this object keeps the slave fd
open for its whole life, because the host (pyserial) opens and closes the port at will and a
pty whose slave has no open fd reports EIO on the master.
"""

from __future__ import annotations

import binascii
import re
from collections.abc import Iterable

import can

from sim_backend.pseudo_terminal import RawPty

_BITRATE_COMMANDS = {
    "S0": 10_000,
    "S1": 20_000,
    "S2": 50_000,
    "S3": 100_000,
    "S4": 125_000,
    "S5": 250_000,
    "S6": 500_000,
    "S7": 750_000,
    "S8": 1_000_000,
    "S9": 83_300,
}
_SJA1000_CAN_CLOCK_HZ = 8_000_000

_OK = b"\r"
_ERROR = b"\a"

_FLAG_DATA_OVERRUN = 0x08
_FLAG_ERROR_PASSIVE = 0x20
_FLAG_BUS_ERROR = 0x80

_MAX_PENDING_OUTPUT_BYTES = 64 * 1024  # the adapter's transmit FIFO to the host
_MAX_COMMAND_BYTES = 64  # a longer line without CR is garbage

_STANDARD_FRAME = re.compile(r"([tr])([0-9A-Fa-f]{3})([0-8])([0-9A-Fa-f]*)")
_EXTENDED_FRAME = re.compile(r"([TR])([0-9A-Fa-f]{8})([0-8])([0-9A-Fa-f]*)")
_BTR = re.compile(r"s([0-9A-Fa-f]{2})([0-9A-Fa-f]{2})")
_ACCEPTANCE = re.compile(r"[Mm][0-9A-Fa-f]{8}")


def bitrate_from_btr(btr0: int, btr1: int) -> float:
    """SJA1000 bit timing registers -> bit/s at the 8 MHz CAN clock.

    BTR0 = SJW-1 (bits 7-6) | BRP-1 (bits 5-0); BTR1 = SAM (bit 7) | TSEG2-1 (bits 6-4) |
    TSEG1-1 (bits 3-0); one bit = (1 + TSEG1 + TSEG2) time quanta of BRP / 8 MHz.
    """
    prescaler = (btr0 & 0x3F) + 1
    quanta_per_bit = 1 + ((btr1 & 0x0F) + 1) + (((btr1 >> 4) & 0x07) + 1)
    return _SJA1000_CAN_CLOCK_HZ / (prescaler * quanta_per_bit)


_HEADS: dict[tuple[int, bool, bool, int], bytes] = {}  # the lines' heads, made once each
_MAX_HEADS = 4096


def encode_frame(msg: can.Message) -> bytes:
    """One bus -> host SLCAN line (without timestamp), e.g. b"t18540F03C0000\\r"."""
    dlc = min(msg.dlc, 8)
    key = (msg.arbitration_id, msg.is_extended_id, msg.is_remote_frame, dlc)
    head = _HEADS.get(key)
    if head is None:
        if msg.is_extended_id:
            text = f"{'R' if msg.is_remote_frame else 'T'}{msg.arbitration_id:08X}{dlc:d}"
        else:
            text = f"{'r' if msg.is_remote_frame else 't'}{msg.arbitration_id:03X}{dlc:d}"
        head = text.encode("ascii")
        if len(_HEADS) < _MAX_HEADS:  # (a node set has a few dozen identifiers)
            _HEADS[key] = head
    if msg.is_remote_frame:
        return head + _OK
    return head + binascii.hexlify(msg.data[:dlc]).upper() + _OK


class SlcanPty:
    """A Lawicel-SLCAN adapter on a pty; see the module docstring for the protocol."""

    def __init__(self, *, bus_bitrate: int = 1_000_000) -> None:
        if bus_bitrate <= 0:
            raise ValueError(f"bus_bitrate must be a positive number of bit/s, got {bus_bitrate}")
        self.bus_bitrate = bus_bitrate
        self._pty = RawPty()
        self.port_path: str = self._pty.path
        self._input = bytearray()
        self._output = bytearray()
        self._bitrate: float | None = None  # set by S/s; None until the host sets one
        self._open = False
        self._listen_only = False
        self._status_flags = 0
        self._closed = False

    # --- state for the emulator's diagnostics ---------------------------------------------
    @property
    def channel_open(self) -> bool:
        """True while the host has the CAN channel open (O or L)."""
        return self._open

    @property
    def bitrate(self) -> float | None:
        """The bitrate the host set (bit/s), or None before any S/s command."""
        return self._bitrate

    @property
    def on_bus(self) -> bool:
        """True when frames flow: channel open at the segment's bitrate."""
        return self._open and self._bitrate_matches()

    def fileno(self) -> int:
        """The master fd: readable when the host has written something."""
        return self._pty.master_fd

    # --- the event-loop API ----------------------------------------------------------------
    def read_frames(self, *, flush: bool = True) -> list[can.Message]:
        """Frames the host sent to the bus since the last call (commands are answered here;
        with flush=False the answers wait for the next `send_frames`/`flush_output`, so that
        they and the nodes' replies reach the host in one write)."""
        self._fill_input()
        frames: list[can.Message] = []
        while True:
            end = self._input.find(b"\r")
            if end < 0:
                if len(self._input) > _MAX_COMMAND_BYTES:
                    self._input.clear()
                    self._queue_output(_ERROR)
                break
            line = bytes(self._input[:end])
            del self._input[: end + 1]
            reply, frame = self._execute(line.decode("ascii", errors="replace").lstrip("\n"))
            self._queue_output(reply)
            if frame is not None:
                frames.append(frame)
        if flush:
            self.flush_output()
        return frames

    def send_frame(self, msg: can.Message) -> None:
        """Pass one frame from the bus to the host (dropped while the adapter is off the bus)."""
        self.send_frames((msg,))

    def send_frames(self, msgs: Iterable[can.Message]) -> None:
        """Pass frames from the bus to the host in one write (with any answers not yet sent):
        a pty write wakes the host, so a SYNC's replies go out together."""
        if self.on_bus:
            for msg in msgs:
                if msg.is_fd or msg.is_error_frame:
                    continue
                line = encode_frame(msg)
                if len(self._output) + len(line) > _MAX_PENDING_OUTPUT_BYTES:
                    self._status_flags |= _FLAG_DATA_OVERRUN  # the host is not reading: drop
                    continue
                self._output += line
        self.flush_output()

    def flush_output(self) -> None:
        """Write what the host has not yet taken (the pty buffer may have been full)."""
        while self._output and not self._closed:
            written = self._pty.write(self._output)
            if not written:
                return
            del self._output[:written]

    def close(self) -> None:
        """Release both ends of the pty. Safe to call twice."""
        if self._closed:
            return
        self._closed = True
        self._pty.close()

    def __enter__(self) -> SlcanPty:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    # --- internals -------------------------------------------------------------------------
    def _fill_input(self) -> None:
        if not self._closed:
            self._input += self._pty.read_available()

    def _queue_output(self, data: bytes) -> None:
        if len(self._output) + len(data) <= _MAX_PENDING_OUTPUT_BYTES:
            self._output += data
        else:
            self._status_flags |= _FLAG_DATA_OVERRUN

    def _bitrate_matches(self) -> bool:
        return self._bitrate is not None and abs(self._bitrate - self.bus_bitrate) <= (
            0.005 * self.bus_bitrate  # CAN tolerates well under 1 % clock mismatch
        )

    def _execute(self, command: str) -> tuple[bytes, can.Message | None]:
        """Reply bytes and the frame for the bus (if the command was a frame to send)."""
        if not command:
            return _OK, None
        head = command[0]
        if head in "tTrR":
            return self._transmit(command)
        if command in _BITRATE_COMMANDS:
            if self._open:
                return _ERROR, None
            self._bitrate = _BITRATE_COMMANDS[command]
            return _OK, None
        if match := _BTR.fullmatch(command):
            if self._open:
                return _ERROR, None
            self._bitrate = bitrate_from_btr(int(match.group(1), 16), int(match.group(2), 16))
            return _OK, None
        if command in ("O", "L"):
            if self._open or self._bitrate is None:
                return _ERROR, None
            self._open = True
            self._listen_only = command == "L"
            return _OK, None
        if command == "C":
            self._open = False
            self._listen_only = False
            return _OK, None
        if command == "V":
            return b"V1013\r", None
        if command == "v":
            return b"v1013\r", None
        if command == "N":
            return b"NFJH1\r", None
        if command == "F":
            if not self._open:
                return _ERROR, None
            flags, self._status_flags = self._status_flags, 0
            return f"F{flags:02X}\r".encode("ascii"), None
        if command == "Z0":
            return (_ERROR, None) if self._open else (_OK, None)
        if _ACCEPTANCE.fullmatch(command):
            return (_ERROR, None) if self._open else (_OK, None)
        return _ERROR, None

    def _transmit(self, command: str) -> tuple[bytes, can.Message | None]:
        match = _STANDARD_FRAME.fullmatch(command) or _EXTENDED_FRAME.fullmatch(command)
        if match is None or not self._open or self._listen_only:
            return _ERROR, None
        kind, identifier, dlc_text, payload = match.groups()
        dlc = int(dlc_text)
        remote = kind in "rR"
        if (remote and payload) or (not remote and len(payload) != 2 * dlc):
            return _ERROR, None
        reply = b"Z\r" if kind in "TR" else b"z\r"
        if not self._bitrate_matches():
            self._status_flags |= _FLAG_ERROR_PASSIVE | _FLAG_BUS_ERROR
            return reply, None  # queued, but never acknowledged on the bus
        frame = can.Message(
            arbitration_id=int(identifier, 16),
            is_extended_id=kind in "TR",
            is_remote_frame=remote,
            dlc=dlc,
            data=None if remote else bytes.fromhex(payload),
        )
        return reply, frame
