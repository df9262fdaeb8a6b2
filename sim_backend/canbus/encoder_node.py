"""Emulated link encoder: a CiA 406 encoder node on CAN (RLS RLC2IC read head + MR075 ring).

The real testbed measures the link angle with an RLS RLC2IC incremental read head on an MR075
ring: 120 poles x 8192 counts per pole = 983,040 counts per revolution (RLS data sheet RLCD02
issue 2: 0.244 um resolution = 8192 counts per 2 mm pole; MR075E: 120 poles). A counter board
turns the A/B quadrature into a count, latches it when SYNC arrives and sends it in a TPDO.
This class is that board as seen on the bus, with the object dictionary of
`sim_backend/data/emulated_cia406_link_encoder.eds`:

    0x1000 device type    0x00020196: CiA 406, encoder type 0x0002 multi-turn absolute
                          rotary. Chosen because the counter counts linearly through any
                          number of turns: a negative link angle is a negative count.
    0x6000 operating      bit 0 code sequence (1 = counting direction reversed); bit 2 (scaling)
           parameters     is refused with abort 0x06090030: the counter has a fixed resolution.
    0x6001 units per rev  read-only, = counts_per_rev (983,040); 0x6501 the same.
    0x6003 preset value   INTEGER32; writing P makes the present position read P.
    0x6004 position value INTEGER32 (CiA 406 v3.2 types; an UNSIGNED32 device sends the same
                          two's-complement bits), PDO-mapped in TPDO1 (0x1A00:01 = 0x60040020).
    0x6500 operating status, mirrors 0x6000.

Position (counts), latched at SYNC from the plant's true link angle:

    counts = wrap_int32(round(s * direction * angle_rad * counts_per_rev / (2*pi)) + preset_offset)

where s = -1 when the code-sequence bit is set, else +1, and `direction` is the mounting
direction of the read head. Rounding is half-up, so any angle maps to the count within half a
count of it. The speed object 0x6030 is not emulated.

Noise (`noise_counts_rms`, 0 unless given; the emulator passes `SensorNoise`'s nominal figure):
zero-mean Gaussian in counts added to the latched value before rounding, seeded (`seed`). The
read head interpolates the ring's magnetic field 8192 times per 2 mm pole; its interpolation
noise makes the count flicker at a count edge. RLS's data sheet (RLCD02 issue 2) gives the
resolution, not a jitter figure; 0.5 count rms (`RLC2IC_NOISE_COUNTS_RMS`) makes the reading
flicker by about one count (rms error of the rounded reading sqrt(0.5^2 + 1/12) = 0.58 count,
3.7 urad), an assumption to be replaced by a measured figure.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from sim_backend.canbus.cia301 import SdoAbortCode
from sim_backend.canbus.object_store import eds_path
from sim_backend.canbus.slave import DEFAULT_BOOTUP_DELAY_S, CanopenSlave, SensorFault

EncoderFault = SensorFault  # the fault type of an encoder node (noise in counts rms)

ENCODER_EDS_FILE = "emulated_cia406_link_encoder.eds"
RLC2IC_MR075_COUNTS_PER_REV = 120 * 8192  # 983,040
RLC2IC_NOISE_COUNTS_RMS = 0.5  # nominal interpolation noise (see the module docstring)

_OPERATING_PARAMETERS = 0x6000
_PRESET_VALUE = 0x6003
_POSITION_VALUE = 0x6004
_CODE_SEQUENCE_BIT = 0x0001
_SCALING_BIT = 0x0004


class LinkEncoderNode(CanopenSlave):
    """A CiA 406 link-encoder node; see the module docstring for its objects and behaviour.

    angle_source: returns the true link angle (rad) at the instant it is called; called once per
    SYNC that the node answers (and per SDO read of 0x6004). noise_counts_rms: the read head's
    noise (0: an ideal counter; the emulator passes the nominal `RLC2IC_NOISE_COUNTS_RMS`).
    """

    def __init__(
        self,
        node_id: int,
        angle_source: Callable[[], float],
        *,
        counts_per_rev: int = RLC2IC_MR075_COUNTS_PER_REV,
        direction: int = +1,
        heartbeat_ms: int = 100,
        seed: int = 0,
        tpdo_transmission_type: int = 1,
        noise_counts_rms: float = 0.0,
        bootup_delay_s: float = DEFAULT_BOOTUP_DELAY_S,
    ) -> None:
        if not callable(angle_source):
            raise TypeError("angle_source must be a callable returning the link angle in rad")
        if not 1 <= counts_per_rev <= 0x7FFF_FFFF:
            raise ValueError(f"counts_per_rev must be 1..2**31-1, got {counts_per_rev}")
        if direction not in (+1, -1):
            raise ValueError(f"direction must be +1 or -1, got {direction}")
        self._angle_source = angle_source
        self._signed_counts_per_rad = direction * counts_per_rev / (2.0 * math.pi)
        self._code_sign = 1
        self._preset_offset_counts = 0
        super().__init__(
            node_id,
            eds_path(ENCODER_EDS_FILE),
            process_value_object=(_POSITION_VALUE, 0),
            heartbeat_ms=heartbeat_ms,
            seed=seed,
            tpdo_transmission_type=tpdo_transmission_type,
            bootup_delay_s=bootup_delay_s,
            serial_number=0x4060_0000 + node_id,
            process_noise_rms=noise_counts_rms,
        )
        self._store.set_default(0x6001, 0, counts_per_rev)
        self._store.set_default(0x6501, 0, counts_per_rev)
        self._store.validate_writes(_OPERATING_PARAMETERS, 0, _refuse_scaling)
        self._store.on_read(0x6500, 0, lambda: self._store.stored_value(_OPERATING_PARAMETERS))

    def _unoffset_counts(self) -> float:
        return self._code_sign * self._signed_counts_per_rad * float(self._angle_source())

    def _ideal_raw(self) -> float:
        # (`_unoffset_counts` written out: a call fewer per SYNC)
        counts = self._code_sign * self._signed_counts_per_rad * float(self._angle_source())
        return counts + self._preset_offset_counts

    def _reset_application(self) -> None:
        self._preset_offset_counts = 0
        self._update_code_sign()

    def _update_code_sign(self) -> None:
        operating_parameters = int(self._store.stored_value(_OPERATING_PARAMETERS))
        self._code_sign = -1 if operating_parameters & _CODE_SEQUENCE_BIT else 1

    def _on_object_written(self, index: int, subindex: int, value: Any) -> None:
        if index == _OPERATING_PARAMETERS:
            self._update_code_sign()
        elif index == _PRESET_VALUE:
            self._preset_offset_counts = int(value) - math.floor(self._unoffset_counts() + 0.5)


def _refuse_scaling(value: int) -> SdoAbortCode | None:
    return SdoAbortCode.VALUE_RANGE_EXCEEDED if value & _SCALING_BIT else None
