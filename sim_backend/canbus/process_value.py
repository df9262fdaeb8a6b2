"""The process value an emulated CAN sensor node serves: the plant's ideal value plus the
sensor's nominal noise and an injected fault's, rounded half up and wrapped like a 32-bit
register; the injectable fault itself (`SensorFault`) and how often it acted (`SensorFaultCounts`).

Nominal noise (`process_noise_rms`, raw units, 0 by default): the sensor's own measurement noise,
zero-mean Gaussian added to every sample before rounding, from the node's seeded Generator (a
"noisy" fault adds its noise on top). Same seed, same calls: the same values.

What "dead" does (power) and when "stale" freezes the value are the node's (`slave.py`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

FAULT_MODES = ("ok", "dead", "stale", "noisy")


@dataclass
class SensorFault:
    """An injectable fault of an emulated sensor node (mutable: the test or plant flips it).

    mode: "ok", "dead" (no frames at all), "stale" (process value frozen), "noisy" (Gaussian
    noise of `noise_counts_rms` raw units, e.g. encoder counts or millinewtons).
    """

    mode: str = "ok"
    noise_counts_rms: float = 0.0

    def check(self) -> None:
        if self.mode not in FAULT_MODES:
            raise ValueError(f"fault mode must be one of {FAULT_MODES}, got {self.mode!r}")
        if not (math.isfinite(self.noise_counts_rms) and self.noise_counts_rms >= 0.0):
            raise ValueError(
                f"noise_counts_rms must be a finite value >= 0, got {self.noise_counts_rms!r}"
            )


@dataclass
class SensorFaultCounts:
    """How often the node's fault actually acted (history, never reset by the node).

    frames_ignored_while_dead: frames on the bus the node did not hear because it had no power.
    stale_samples: process values served frozen (SYNC answers and SDO reads) while "stale".
    noisy_samples: process values that got noise added while "noisy".
    """

    frames_ignored_while_dead: int = 0
    stale_samples: int = 0
    noisy_samples: int = 0


def wrap_int32(value: int) -> int:
    """Two's-complement wrap of a counter to the INTEGER32 range, like a 32-bit register."""
    return ((value + 0x8000_0000) & 0xFFFF_FFFF) - 0x8000_0000


class ProcessValue:
    """The sampling of `CanopenSlave` (sim_backend/canbus/slave.py), a mixin: the node sets
    `fault`, `fault_counts` and `_normals` and supplies `_ideal_raw`."""

    def _set_process_noise(self, rms_raw: float) -> None:
        """The sensor's nominal noise, rms in raw units (for subclasses that scale a figure)."""
        if not (math.isfinite(rms_raw) and rms_raw >= 0.0):
            raise ValueError(f"the sensor noise must be a finite rms >= 0, got {rms_raw!r}")
        self._process_noise_rms = float(rms_raw)

    def _sample_raw(self) -> int:
        """The process value now, in raw units, with the fault applied (the read hook)."""
        if self._frozen_raw is not None:
            self.fault_counts.stale_samples += 1
            return self._frozen_raw
        exact = self._ideal_raw()
        if not math.isfinite(exact):
            raise ValueError(
                f"node {self.node_id}: the plant's source gave a non-finite value ({exact!r})"
            )
        if self._process_noise_rms > 0.0:
            exact += self._normals.next() * self._process_noise_rms
        if self.fault.mode == "noisy" and self.fault.noise_counts_rms > 0.0:
            exact += self._normals.next() * self.fault.noise_counts_rms
            self.fault_counts.noisy_samples += 1
        raw = wrap_int32(math.floor(exact + 0.5))  # round half up
        self._last_sample_raw = raw
        return raw
