"""Emulated contact force sensor: a CiA 404 measuring-device node on CAN.

The paper's testbed had a force sensor at the obstacle, but its model and interface are not
published. ASSUMPTION (documented choice, not a fact about the testbed): it is emulated as a
CiA 404 device with one analogue input channel whose process value is latched on SYNC and sent
in TPDO1, with the object dictionary of `sim_backend/data/emulated_cia404_force_sensor.eds`:

    0x1000   device type          0x00020194: CiA 404, "analogue input block" (coding as in the
                                  Axiomatic AX030541 manual, section 3.2.1)
    0x6131:1 AI physical unit PV  0x00210000: newton, prefix 10^0 (CiA 303-2: byte 2 = unit,
                                  byte 3 = signed decimal exponent)
    0x6132:1 AI decimal digits PV 3
    0x9130:1 AI input PV          INTEGER32, PDO-mapped in TPDO1 (0x1A00:01 = 0x91300120)

(object layout as in the esd CAN-CBX-THERMO manual, sections 8.10.7/8.10.8/8.10.12), so

    PV = round(force_n / 10**prefix * 10**decimal_digits)   i.e. millinewtons,

resolution 1 mN, range +-2.1 MN. Faults as for every emulated node (`SensorFault`); the noise
is in PV units (mN rms).

Noise (`noise_n_rms`, 0 unless given; the emulator passes `SensorNoise`'s nominal figure):
zero-mean Gaussian in newtons added before rounding, seeded (`seed`). The paper names no sensor,
so the figure is an ASSUMPTION: 0.05 N rms (`FORCE_SENSOR_NOISE_N_RMS`), 0.05 % of a 100 N
range, the order of a strain-gauge load cell read through a bridge amplifier.
"""

from __future__ import annotations

from collections.abc import Callable

from sim_backend.canbus.object_store import eds_path
from sim_backend.canbus.slave import DEFAULT_BOOTUP_DELAY_S, CanopenSlave

FORCE_SENSOR_EDS_FILE = "emulated_cia404_force_sensor.eds"
FORCE_SENSOR_NOISE_N_RMS = 0.05  # nominal (an assumption; see the module docstring)

_PHYSICAL_UNIT = 0x6131
_DECIMAL_DIGITS = 0x6132
_PROCESS_VALUE = 0x9130


class ForceSensorNode(CanopenSlave):
    """A CiA 404 force-sensor node; see the module docstring for its objects and behaviour.

    force_source: returns the contact force (N) at the instant it is called; called once per
    SYNC that the node answers (and per SDO read of 0x9130:01). noise_n_rms: the sensor's noise
    (0: ideal; the emulator passes the nominal `FORCE_SENSOR_NOISE_N_RMS`).
    """

    def __init__(
        self,
        node_id: int,
        force_source: Callable[[], float],
        *,
        heartbeat_ms: int = 100,
        seed: int = 0,
        tpdo_transmission_type: int = 1,
        noise_n_rms: float = 0.0,
        bootup_delay_s: float = DEFAULT_BOOTUP_DELAY_S,
    ) -> None:
        if not callable(force_source):
            raise TypeError("force_source must be a callable returning the force in N")
        self._force_source = force_source
        self._counts_per_newton = 1.0
        super().__init__(
            node_id,
            eds_path(FORCE_SENSOR_EDS_FILE),
            process_value_object=(_PROCESS_VALUE, 1),
            heartbeat_ms=heartbeat_ms,
            seed=seed,
            tpdo_transmission_type=tpdo_transmission_type,
            bootup_delay_s=bootup_delay_s,
            serial_number=0x4040_0000 + node_id,
        )
        unit = int(self._store.stored_value(_PHYSICAL_UNIT, 1))
        prefix_exponent = int.from_bytes(bytes([unit >> 24]), "little", signed=True)
        decimal_digits = int(self._store.stored_value(_DECIMAL_DIGITS, 1))
        self._counts_per_newton = 10.0 ** (decimal_digits - prefix_exponent)
        self._set_process_noise(noise_n_rms * self._counts_per_newton)

    def _ideal_raw(self) -> float:
        return float(self._force_source()) * self._counts_per_newton
